"""Lint: the whole tree passes ruff (pycodestyle, pyflakes, isort, bugbear; 99 columns)."""
import re
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


def test_readme_venv_is_not_linted():
    """The README's ROS-free venv (created inside the clone) is outside the lint.

    Following "Tests without ROS" creates e.g. ``.venv312/`` in the tree; its ``bin/em.py``
    (EmPy's script) has hundreds of ruff findings, so ``test_ruff_clean`` failed there.
    """
    pytest.importorskip('ruff')
    readme = (ROOT / 'README.md').read_text(encoding='utf-8')
    names = set(re.findall(r'-m venv (\.venv\w*)', readme))
    assert names, 'README names no venv'
    for name in names:
        proc = subprocess.run(
            [sys.executable, '-m', 'ruff', 'check', '--no-cache', '--force-exclude',
             '--stdin-filename', str(ROOT / name / 'bin' / 'em.py'), '-'],
            input='import os\nx=1;y=2\n', capture_output=True, text=True, cwd=ROOT)
        assert proc.returncode == 0, f'{name}: ' + proc.stdout + proc.stderr
