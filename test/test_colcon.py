"""colcon builds the package as ros.ament_python into the layout ``ros2 run`` resolves."""
from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import time
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


def _installed_env(prefix: Path, domain: int) -> dict[str, str]:
    """Environment of a sourced install without setup.bash: the install's site-packages on
    PYTHONPATH (ahead of the venv's editable install) and the prefix on AMENT_PREFIX_PATH."""
    site = next(prefix.glob('lib/python3*/site-packages'))
    return dict(os.environ, PYTHONPATH=str(site), AMENT_PREFIX_PATH=str(prefix),
                ROS_DOMAIN_ID=str(domain))


def test_installed_nodes_talk_over_dds(colcon_ws, tmp_path):
    """Installed inertia_estimator (installed params file) + scene_simulator publish an estimate.

    Both run as separate processes from lib/inertia_ros, importing the installed package;
    this process listens on a private ROS_DOMAIN_ID for ~/inertia.
    """
    rclpy = pytest.importorskip('rclpy')
    from geometry_msgs.msg import InertiaStamped
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node

    from inertia_ros.cli.demo import stop_processes, wait_until_matched

    prefix = colcon_ws / 'install' / 'inertia_ros'
    domain = 221 + os.getpid() % 11
    env = _installed_env(prefix, domain)
    lib = prefix / 'lib' / 'inertia_ros'
    params = prefix / 'share' / 'inertia_ros' / 'config' / 'inertia_estimator.yaml'
    cmds = {
        'estimator': [str(lib / 'inertia_estimator'), '--ros-args', '--params-file', str(params)],
        # The default scene from the installed share/ (ament index), at 10x real time.
        'simulator': [str(lib / 'scene_simulator'), '--ros-args', '-p', 'rate:=10.0',
                      '-p', 'wait_for_subscribers:=1', '-p', 'exit_on_end:=true'],
    }
    logs = {k: open(tmp_path / f'{k}.log', 'w') for k in cmds}
    procs: dict[str, subprocess.Popen] = {}

    def start(k: str) -> None:
        procs[k] = subprocess.Popen(cmds[k], env=env, cwd=tmp_path, stdout=logs[k],
                                    stderr=subprocess.STDOUT)

    ctx = rclpy.context.Context()
    rclpy.init(context=ctx, domain_id=domain)
    got = []
    try:
        node = Node('colcon_listener', context=ctx)
        sub = node.create_subscription(InertiaStamped, '/inertia_estimator/inertia',
                                       got.append, 10)
        exe = SingleThreadedExecutor(context=ctx)
        exe.add_node(node)
        start('estimator')
        # The scene starts once this listener has discovered the estimator's output.
        problem = wait_until_matched(lambda: exe.spin_once(timeout_sec=0.05), [sub],
                                     procs['estimator'], 30.0)
        if not problem:
            start('simulator')
            end = time.monotonic() + 40.0
            while time.monotonic() < end and len(got) < 3:
                exe.spin_once(timeout_sec=0.05)
                if procs['estimator'].poll() is not None:
                    break
        exe.shutdown()
        node.destroy_node()
    finally:
        rclpy.try_shutdown(context=ctx)
        stop_processes(list(procs.values()))
        for f in logs.values():
            f.close()
    text = {k: (tmp_path / f'{k}.log').read_text() for k in cmds}
    assert not problem, f"{problem}\n{text['estimator'][-2000:]}"
    assert got, f"no estimate over DDS\n{text['estimator'][-2000:]}\n{text['simulator'][-2000:]}"
    assert str(prefix / 'share' / 'inertia_ros' / 'config' / 'scenes') in text['simulator']
    assert got[-1].header.frame_id == 'base_link'
