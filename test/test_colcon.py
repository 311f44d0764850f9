"""colcon builds the package as ros.ament_python into the layout ``ros2 run`` resolves."""
from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import ROOT

pytestmark = pytest.mark.slow

IGNORE = shutil.ignore_patterns('.venv', 'build', 'install', 'log', '.git', '__pycache__',
                                '*.egg-info', '.pytest_cache', '.ruff_cache', '.hypothesis',
                                'demo_out', 'bench_out')


def registered_executables() -> list[str]:
    """Console scripts declared in setup.py (each becomes lib/inertia_ros/NAME)."""
    text = (ROOT / 'setup.py').read_text()
    return re.findall(r"'([\w-]+) = inertia_ros\.[\w.]+:\w+'", text)


@pytest.fixture(scope='module')
def colcon_ws(tmp_path_factory) -> Path:
    """A workspace with the package copied into src/ and built with colcon."""
    ws = tmp_path_factory.mktemp('ws')
    shutil.copytree(ROOT, ws / 'src' / 'inertia_ros', ignore=IGNORE)
    colcon = Path(sys.executable).with_name('colcon')
    env = dict(os.environ, PATH=f'{Path(sys.executable).parent}{os.pathsep}{os.environ["PATH"]}')
    proc = subprocess.run(
        [str(colcon), 'build', '--base-paths', 'src', '--event-handlers', 'console_direct+'],
        cwd=ws, env=env, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    return ws


def test_colcon_recognises_ros_ament_python(colcon_ws):
    """colcon identifies the package type from package.xml, not as a plain Python package."""
    log = (colcon_ws / 'log' / 'latest_build' / 'logger_all.log').read_text()
    assert "Package 'src/inertia_ros' with type 'ros.ament_python'" in log


def test_install_layout(colcon_ws):
    """The install prefix holds the ament index marker, package.xml, config and executables."""
    prefix = colcon_ws / 'install' / 'inertia_ros'
    assert (prefix / 'share/ament_index/resource_index/packages/inertia_ros').is_file()
    assert (prefix / 'share/inertia_ros/package.xml').is_file()
    for cfg in (ROOT / 'config').glob('*.yaml'):
        assert (prefix / 'share/inertia_ros/config' / cfg.name).is_file()
    for scene in (ROOT / 'config' / 'scenes').glob('*.yaml'):
        assert (prefix / 'share/inertia_ros/config/scenes' / scene.name).is_file()
    installed = sorted(p.name for p in (prefix / 'lib/inertia_ros').glob('*')
                       if p.is_file() and os.access(p, os.X_OK)) \
        if (prefix / 'lib/inertia_ros').is_dir() else []
    assert installed == sorted(registered_executables())
