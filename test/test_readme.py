"""The README stays true: its Python example runs and the commands it shows exist."""
import os
import re
import subprocess
import sys

from conftest import ROOT

README = (ROOT / 'README.md').read_text()


def test_python_examples_run():
    """Every ```python block of the README runs from the repository root without error."""
    blocks = re.findall(r'```python\n(.*?)```', README, flags=re.S)
    assert blocks, 'README has no Python example'
    for code in blocks:
        proc = subprocess.run([sys.executable, '-c', code], cwd=ROOT, capture_output=True,
                              text=True, timeout=120,
                              env=dict(os.environ, MPLBACKEND='Agg'))
        assert proc.returncode == 0, proc.stderr[-2000:]


def test_shown_commands_are_registered():
    """Every `python -m inertia_ros COMMAND` in the README is a registered command."""
    from inertia_ros.cli import COMMANDS
    shown = set(re.findall(r'python -m inertia_ros (\w+)', README))
    assert shown and shown <= set(COMMANDS), sorted(shown - set(COMMANDS))


def test_referenced_files_exist():
    """Files and images the README links to are in the repository."""
    for ref in re.findall(r'\]\(((?:docs|config|bags)/[^)]+)\)', README):
        assert (ROOT / ref).exists(), ref
