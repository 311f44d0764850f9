"""Lint: the whole tree passes ruff (pycodestyle, pyflakes, isort, bugbear; 99 columns)."""
import subprocess
import sys

import pytest

from conftest import ROOT


def test_ruff_clean():
    """Every Python file passes the project's ruff configuration (see pyproject.toml)."""
    pytest.importorskip('ruff')  # optional test dependency (python3-ruff-pip)
    proc = subprocess.run([sys.executable, '-m', 'ruff', 'check', '--no-cache', str(ROOT)],
                          capture_output=True, text=True, cwd=ROOT)
    assert proc.returncode == 0, proc.stdout + proc.stderr
