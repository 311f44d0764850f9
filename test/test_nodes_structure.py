"""Shape of the nodes package (issue 26): nodes wire ROS to the core, logic lives elsewhere.

No module under ``inertia_ros/nodes`` over 800 lines, no function over 80, no class over 400
(the estimator node was 935 lines with a 680-line class); the estimator's non-ROS parts
(estimator selection, input admission, feeding, the params-file check) import no rclpy, so
they can be used and tested without ROS.
"""
from __future__ import annotations

import ast
import json
import subprocess
import sys

import pytest

from conftest import ROOT

NODES = ROOT / 'inertia_ros' / 'nodes'
SOURCES = sorted(NODES.glob('*.py'))
MAX_MODULE_LINES, MAX_CLASS_LINES, MAX_FUNCTION_LINES = 800, 400, 80
#: The estimator's helpers without ROS (only numpy, the core, io codecs, yaml).
ROS_FREE = ('selection', 'admission', 'feed', 'params_file')


def _span(node: ast.AST) -> int:
    return node.end_lineno - node.lineno + 1


@pytest.mark.parametrize('path', SOURCES, ids=lambda p: p.name)
def test_nodes_module_is_small(path) -> None:
    """Module <= 800 lines, class <= 400, function (docstring included) <= 80."""
    text = path.read_text()
    n = len(text.splitlines())
    assert n <= MAX_MODULE_LINES, f'{path.name}: {n} lines'
    too_long = [f'{x.name} ({_span(x)} lines)' for x in ast.walk(ast.parse(text))
                if (isinstance(x, ast.ClassDef) and _span(x) > MAX_CLASS_LINES)
                or (isinstance(x, (ast.FunctionDef, ast.AsyncFunctionDef))
                    and _span(x) > MAX_FUNCTION_LINES)]
    assert not too_long, f'{path.name}: ' + ', '.join(too_long)


def test_estimator_helpers_import_no_ros() -> None:
    """Importing the estimator's helpers in a fresh interpreter loads no rclpy or messages."""
    mods = [f'inertia_ros.nodes.{m}' for m in ROS_FREE]
    code = ('import importlib, json, sys\n'
            f'for m in {mods!r}:\n'
            '    importlib.import_module(m)\n'
            'print(json.dumps(sorted(m for m in sys.modules if m.split(".")[0] == "rclpy"\n'
            '                        or m.split(".")[0].endswith("_msgs"))))\n')
    proc = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                          cwd=ROOT, check=False)
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout.strip().splitlines()[-1]) == []
