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


# --------------------------------------------------------------------------- ROS in one place
PKG = ROOT / 'inertia_ros'
ROS_ROOTS = ('rclpy', 'rcl_interfaces', 'builtin_interfaces', 'std_srvs',
             'ament_index_python', 'rosidl_runtime_py')
#: Modules outside nodes/ that may reach the nodes, inside a function only (lazily).
LAZY_NODE_USERS = ('inertia_ros/inertia_estimator_node.py', 'inertia_ros/scene_simulator_node.py',
                   'inertia_ros/bag_player_node.py', 'inertia_ros/exciter_node.py',
                   'inertia_ros/cli/demo.py',
                   'inertia_ros/bench/node.py')


def _is_ros(name):
    root = name.split('.')[0]
    return root in ROS_ROOTS or root.endswith('_msgs')


def _imports(path):
    """(module name, line, at module level?) of every import in a source file."""
    tree = ast.parse(path.read_text(), filename=str(path))
    top = {id(n) for n in tree.body}
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                yield a.name, node.lineno, id(node) in top
        elif isinstance(node, ast.ImportFrom):
            yield _absolute(path, node), node.lineno, id(node) in top


def _sources(under):
    return sorted((PKG / under).rglob('*.py')) if under else sorted(PKG.rglob('*.py'))


def test_io_never_imports_ros_or_nodes():
    """io/ imports no rclpy, no ROS message package and not inertia_ros.nodes, even lazily."""
    offenders = [f'{p.relative_to(ROOT)}:{line}: {name}'
                 for p in _sources('io') for name, line, _ in _imports(p)
                 if _is_ros(name) or name == 'inertia_ros.nodes'
                 or name.startswith('inertia_ros.nodes.')]
    assert offenders == []


def test_ros_is_imported_only_under_nodes():
    """rclpy and message packages only in inertia_ros/nodes/; the node shims and the demo
    reach nodes/ lazily (inside a function), nobody else reaches it at all."""
    offenders = []
    for p in _sources(''):
        rel = p.relative_to(ROOT).as_posix()
        if rel.startswith('inertia_ros/nodes/'):
            continue
        for name, line, top in _imports(p):
            to_nodes = name == 'inertia_ros.nodes' or name.startswith('inertia_ros.nodes.')
            if _is_ros(name) or (to_nodes and (top or rel not in LAZY_NODE_USERS)):
                offenders.append(f'{rel}:{line}: {name}')
    assert offenders == []


def test_options_module_imports_nothing():
    """core/estimation/options.py imports nothing (it keeps --help and parameter tables fast)."""
    path = PKG / 'core' / 'estimation' / 'options.py'
    names = [name for name, _, _ in _imports(path) if name != '__future__']
    assert names == []


def test_entry_points_and_cli_load_no_ros_until_run():
    """Importing the node shims, io and the CLI (with --help) loads neither rclpy nor nodes/."""
    mods = ['inertia_ros.inertia_estimator_node', 'inertia_ros.scene_simulator_node',
            'inertia_ros.bag_player_node', 'inertia_ros.cli', 'inertia_ros.cli.demo']
    mods += [f'inertia_ros.io.{p.stem}' for p in _sources('io') if p.stem != '__init__']
    code = (
        'import importlib, json, sys\n'
        f'for m in {mods!r}:\n'
        '    importlib.import_module(m)\n'
        'bad = sorted(m for m in sys.modules if m.split(".")[0] in ("rclpy",)\n'
        '             or m.split(".")[0].endswith("_msgs") or m.startswith("inertia_ros.nodes"))\n'
        'print(json.dumps(bad))\n'
    )
    proc = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                          cwd=ROOT, check=False)
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout.strip().splitlines()[-1]) == []
