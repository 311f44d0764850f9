"""Architecture: the core is pure numpy/scipy and never pulls in ROS or MCAP code."""
import ast
import json
import subprocess
import sys

from conftest import ROOT

FORBIDDEN = ('rclpy', 'mcap', 'mcap_ros2', 'rosbags', 'geometry_msgs', 'sensor_msgs',
             'std_msgs', 'diagnostic_msgs', 'visualization_msgs', 'std_srvs', 'yaml',
             'matplotlib')


def _core_modules():
    core = ROOT / 'inertia_ros' / 'core'
    mods = []
    for path in sorted(core.rglob('*.py')):
        rel = path.relative_to(ROOT).with_suffix('')
        parts = list(rel.parts)
        if parts[-1] == '__init__':
            parts = parts[:-1]
        mods.append('.'.join(parts))
    return mods


def test_core_imports_no_ros_or_mcap_at_runtime():
    """Importing every core module in a fresh interpreter loads none of the forbidden modules."""
    mods = _core_modules()
    assert 'inertia_ros.core' in mods
    code = (
        'import importlib, json, sys\n'
        f'for m in {mods!r}:\n'
        '    importlib.import_module(m)\n'
        f'bad = sorted(m for m in sys.modules if m.split(".")[0] in {FORBIDDEN!r})\n'
        'print(json.dumps(bad))\n'
    )
    proc = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                          cwd=ROOT, check=False)
    assert proc.returncode == 0, proc.stderr
    loaded = json.loads(proc.stdout.strip().splitlines()[-1])
    assert loaded == [], f'inertia_ros.core pulled in {loaded}'


def _absolute(path, node):
    """The absolute module an ImportFrom names, resolving relative imports from ``path``."""
    if node.level == 0:
        return node.module or ''
    package = list(path.relative_to(ROOT).with_suffix('').parts[:-1])
    base = package[:len(package) - (node.level - 1)]
    return '.'.join(base + ([node.module] if node.module else []))


def test_core_source_has_no_forbidden_imports():
    """No core source file imports ROS, MCAP or inertia_ros outside core, even lazily."""
    offenders = []
    for path in (ROOT / 'inertia_ros' / 'core').rglob('*.py'):
        tree = ast.parse(path.read_text(), filename=str(path))
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                names = [_absolute(path, node)]
            else:
                continue
            for n in names:
                root = n.split('.')[0]
                inside = n == 'inertia_ros.core' or n.startswith('inertia_ros.core.')
                if root in FORBIDDEN or (root == 'inertia_ros' and not inside):
                    offenders.append(f'{path.relative_to(ROOT)}:{node.lineno}: {n}')
    assert offenders == []
