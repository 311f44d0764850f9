"""Shape of the io package (issue 26): one job per module, small functions.

No module under ``inertia_ros/io`` over 800 lines, no function over 80, no class over 400
(``mcap_reader.py`` was 1738 lines doing every job of the reader, with a 647-line class and a
167-line ``iter_batches``; ``decode_batch`` was 135 lines, ``write_simulation`` 105).  The
MCAP reader's layers build on each other in one direction: records, codecs, scanning,
chunks, the reader.
"""
from __future__ import annotations

import ast

import pytest

from conftest import ROOT

IO = ROOT / 'inertia_ros' / 'io'
SOURCES = sorted(IO.glob('*.py'))
MAX_MODULE_LINES, MAX_CLASS_LINES, MAX_FUNCTION_LINES = 800, 400, 80
#: The reader's modules, lowest layer first: each imports only those before it.
READER_LAYERS = ('mcap_records', 'mcap_codecs', 'mcap_scan', 'mcap_chunks', 'mcap_reader')


def _span(node: ast.AST) -> int:
    return node.end_lineno - node.lineno + 1


@pytest.mark.parametrize('path', SOURCES, ids=lambda p: p.name)
def test_io_module_is_small(path) -> None:
    """Module <= 800 lines, class <= 400, function (docstring included) <= 80."""
    text = path.read_text()
    n = len(text.splitlines())
    assert n <= MAX_MODULE_LINES, f'{path.name}: {n} lines'
    too_long = [f'{x.name} ({_span(x)} lines)' for x in ast.walk(ast.parse(text))
                if (isinstance(x, ast.ClassDef) and _span(x) > MAX_CLASS_LINES)
                or (isinstance(x, (ast.FunctionDef, ast.AsyncFunctionDef))
                    and _span(x) > MAX_FUNCTION_LINES)]
    assert not too_long, f'{path.name}: ' + ', '.join(too_long)


@pytest.mark.parametrize('k', range(len(READER_LAYERS)), ids=lambda k: READER_LAYERS[k])
def test_reader_layers_import_downwards_only(k: int) -> None:
    """Each layer of the MCAP reader imports only lower layers (no cycles, no back edges)."""
    tree = ast.parse((IO / f'{READER_LAYERS[k]}.py').read_text())
    used = {node.module.rsplit('.', 1)[-1] for node in ast.walk(tree)
            if isinstance(node, ast.ImportFrom) and node.module
            and node.module.rsplit('.', 1)[-1] in READER_LAYERS}
    assert used <= set(READER_LAYERS[:k]), f'{READER_LAYERS[k]} imports {sorted(used)}'
