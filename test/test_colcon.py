"""colcon builds the package as ros.ament_python into the layout ``ros2 run`` resolves, and
``colcon test`` runs the pytest suite.

The workspace is built with the README's own ``colcon build`` line (pip route), so the README
command is verified with the pinned colcon.
"""
from __future__ import annotations

import json
import os
import re
import shlex
import shutil
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
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


def readme_colcon_commands() -> list[list[str]]:
    """The ``colcon ...`` lines of the README's pip-route block (In a ROS 2 workspace)."""
    readme = (ROOT / 'README.md').read_text()
    section = readme[readme.index('## In a ROS 2 workspace'):]
    blocks = re.findall(r'```sh\n(.*?)```', section, flags=re.S)
    pip_block = next(b for b in blocks if 'requirements-test.txt' in b)
    cmds = []
    for line in pip_block.splitlines():
        for part in line.split('&&'):
            if part.strip().startswith('colcon '):
                cmds.append(shlex.split(part))
    return cmds


def _colcon(ws: Path, *args: str, timeout: float = 600) -> subprocess.CompletedProcess:
    colcon = Path(sys.executable).with_name('colcon')
    env = dict(os.environ, PATH=f'{Path(sys.executable).parent}{os.pathsep}{os.environ["PATH"]}')
    # The outer pytest's settings must not leak into the inner runs.
    for var in ('PYTEST_ADDOPTS', 'PYTEST_CURRENT_TEST'):
        env.pop(var, None)
    return subprocess.run([str(colcon), *args], cwd=ws, env=env, capture_output=True,
                          text=True, timeout=timeout)


@pytest.fixture(scope='module')
def colcon_ws(tmp_path_factory) -> Path:
    """A workspace with the package copied into src/ and built with the README's command."""
    ws = tmp_path_factory.mktemp('ws')
    shutil.copytree(ROOT, ws / 'src' / 'inertia_ros', ignore=IGNORE)
    (build,) = [c for c in readme_colcon_commands() if c[1] == 'build']
    proc = _colcon(ws, *build[1:], '--event-handlers', 'console_direct+')
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    return ws


def test_readme_commands_select_the_package():
    """The README's colcon commands (build, test, test-result) use options the pinned colcon
    has: --paths, not --packages-select (colcon-package-selection is not pinned)."""
    cmds = readme_colcon_commands()
    assert [c[1] for c in cmds] == ['build', 'test', 'test-result']
    assert cmds[0] == ['colcon', 'build', '--paths', 'src/inertia_ros']
    assert not any('--packages-select' in c for c in cmds)


def test_colcon_recognises_ros_ament_python(colcon_ws):
    """colcon identifies the package type from package.xml, not as a plain Python package."""
    log = (colcon_ws / 'log' / 'latest_build' / 'logger_all.log').read_text()
    assert re.search(r"Package '[^']*src/inertia_ros' with type 'ros\.ament_python' and name "
                     r"'inertia_ros'", log), log[-3000:]
    assert "with build type 'ament_python'" in log


def test_install_layout(colcon_ws):
    """The install prefix holds the ament index marker, package.xml, LICENSE, config, launch
    files, RViz/Foxglove layouts and executables; the pinned colcon writes setup.sh (no
    colcon-bash, hence no setup.bash)."""
    prefix = colcon_ws / 'install' / 'inertia_ros'
    assert (colcon_ws / 'install' / 'setup.sh').is_file()
    assert (prefix / 'share/inertia_ros/LICENSE').read_text() == (ROOT / 'LICENSE').read_text()
    for extra in ('config/inertia_ros.rviz', 'config/foxglove_layout.json'):
        assert (prefix / 'share/inertia_ros' / extra).is_file(), extra
    for launch in (ROOT / 'launch').glob('*.launch.xml'):
        assert (prefix / 'share/inertia_ros/launch' / launch.name).is_file()
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


@pytest.mark.parametrize('name', ['estimator.launch.xml', 'sim.launch.xml', 'replay.launch.xml'])
def test_installed_launch_files_resolve(colcon_ws, name):
    """Each installed launch file passes test_launch's checks with $(find-pkg-share
    inertia_ros) resolved in the install prefix: every file it names is installed."""
    from test_launch import check_launch_file

    share = colcon_ws / 'install' / 'inertia_ros' / 'share' / 'inertia_ros'

    def installed(rel: str) -> Path | None:
        return share / rel if (share / rel).exists() else None

    assert check_launch_file(share / 'launch' / name, installed)


def test_installed_offline_cli(colcon_ws, tmp_path):
    """The installed ``inertia-ros`` console script runs the offline CLI on an installed log."""
    prefix = colcon_ws / 'install' / 'inertia_ros'
    env = _installed_env(prefix, 0)
    exe = prefix / 'lib' / 'inertia_ros' / 'inertia-ros'
    proc = subprocess.run([str(exe), '--help'], env=env, cwd=tmp_path, capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert 'estimate' in proc.stdout and 'simulate' in proc.stdout
    bag = prefix / 'share' / 'inertia_ros' / 'bags' / 'default.mcap'
    proc = subprocess.run([str(exe), 'estimate', str(bag), '--method', 'integral',
                           '--format', 'json', '--no-progress'], env=env, cwd=tmp_path,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    report = json.loads(proc.stdout)
    assert report['status'] == 'ok'


def _collected(text: str) -> int:
    """Number of tests in pytest's ``--collect-only -q`` summary line."""
    m = re.search(r'^(\d+) tests? collected', text, flags=re.M)
    assert m, text[-3000:]
    return int(m.group(1))


def test_colcon_test_runs_the_suite_with_pytest(colcon_ws):
    """``colcon test`` uses pytest (the setup.py test extra), collects the whole suite without
    a collection error, and its results land in the JUnit file colcon test-result reads.

    Collection of everything, plus a real run of two quick modules, keeps this short.
    """
    src = colcon_ws / 'src' / 'inertia_ros'
    proc = _colcon(colcon_ws, 'test', '--paths', 'src/inertia_ros',
                   '--event-handlers', 'console_direct+',
                   '--pytest-args', ' --collect-only', ' -q', ' -p', ' no:cacheprovider')
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0, out[-3000:]
    assert 'ERROR collecting' not in out and 'during collection' not in out, out[-3000:]
    # Every test function of every module is collected at least once (parametrisation adds).
    functions = sum(len(re.findall(r'^def test_', f.read_text(), flags=re.M))
                    for f in (src / 'test').glob('test_*.py'))
    assert _collected(out) >= functions > 100, (_collected(out), functions)

    proc = _colcon(colcon_ws, 'test', '--paths', 'src/inertia_ros',
                   '--pytest-args', ' test/test_package.py', ' test/test_launch.py')
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    junit = ET.parse(colcon_ws / 'build' / 'inertia_ros' / 'pytest.xml').getroot()
    suite = junit if junit.tag == 'testsuite' else junit.find('testsuite')
    assert int(suite.get('tests')) > 10
    assert int(suite.get('failures')) == 0 and int(suite.get('errors')) == 0
    result = _colcon(colcon_ws, 'test-result', '--verbose')
    assert result.returncode == 0, result.stdout[-3000:]
    assert re.search(r'Summary: \d+ tests, 0 errors, 0 failures', result.stdout), result.stdout


def _installed_env(prefix: Path, domain: int) -> dict[str, str]:
    """Environment of a sourced install without setup.bash: the install's site-packages on
    PYTHONPATH (ahead of the venv's editable install) and the prefix on AMENT_PREFIX_PATH."""
    site = next(prefix.glob('lib/python3*/site-packages'))
    return dict(os.environ, PYTHONPATH=str(site), AMENT_PREFIX_PATH=str(prefix),
                ROS_DOMAIN_ID=str(domain))


@pytest.mark.ros
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
