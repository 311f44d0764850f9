"""Shape of the io package (issue 26): the MCAP reader's layers build on each other in one
direction: records, codecs, scanning, chunks, the reader.  (The size limits of every module,
io included, are checked once in ``test_package_shape.py``.)
"""
from __future__ import annotations

import ast

import pytest

from conftest import ROOT

IO = ROOT / 'inertia_ros' / 'io'
#: The reader's modules, lowest layer first: each imports only those before it.
READER_LAYERS = ('mcap_records', 'mcap_codecs', 'mcap_scan', 'mcap_chunks', 'mcap_reader')


@pytest.mark.parametrize('k', range(len(READER_LAYERS)), ids=lambda k: READER_LAYERS[k])
def test_reader_layers_import_downwards_only(k: int) -> None:
    """Each layer of the MCAP reader imports only lower layers (no cycles, no back edges)."""
    tree = ast.parse((IO / f'{READER_LAYERS[k]}.py').read_text())
    used = {node.module.rsplit('.', 1)[-1] for node in ast.walk(tree)
            if isinstance(node, ast.ImportFrom) and node.module
            and node.module.rsplit('.', 1)[-1] in READER_LAYERS}
    assert used <= set(READER_LAYERS[:k]), f'{READER_LAYERS[k]} imports {sorted(used)}'
