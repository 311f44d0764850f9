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


def test_core_source_has_no_forbidden_imports():
    """No core source file names a forbidden module in an import statement (even lazily)."""
    offenders = []
    for path in (ROOT / 'inertia_ros' / 'core').rglob('*.py'):
        tree = ast.parse(path.read_text(), filename=str(path))
        for node in ast.walk(tree):
            names = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                names = [node.module]
            elif isinstance(node, ast.ImportFrom) and node.level > 0 and node.module:
                # relative import climbing out of core into io/nodes/cli
                if node.level >= 2 and not node.module.startswith('core'):
                    offenders.append(f'{path.name}:{node.lineno}: relative {node.module}')
            for n in names:
                if n.split('.')[0] in FORBIDDEN:
                    offenders.append(f'{path.name}:{node.lineno}: {n}')
                if n.startswith('inertia_ros.') and not n.startswith('inertia_ros.core'):
                    offenders.append(f'{path.name}:{node.lineno}: {n}')
    assert offenders == []
