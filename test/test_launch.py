"""Launch files, RViz and Foxglove configurations: everything they name exists.

The ROS 2 launch packages are not available as wheels, so the XML launch files are checked
statically (xml.etree): every node's package and executable is a console script of setup.py,
every parameter is in the node's parameter table (``config/<executable>.yaml``, which
test_nodes.py keeps equal to the declared parameters) with a value of the declared type, every
remap renames a topic the node uses, every ``$(var ...)`` is a declared argument, every
included file gets the arguments it declares (and only those), and every file path resolves,
through setup.py's data_files, to a file of the installed ``share/inertia_ros`` layout that
exists in the source tree.  test_colcon.py runs the same checks on a colcon install.

The visualisation configurations parse (YAML / JSON) and name only topics the estimator
publishes (scanned from its create_publisher calls, listed in docs/DESIGN.md), with message
fields that exist.
"""
from __future__ import annotations

import ast
import json
import re
import xml.etree.ElementTree as ET
from collections.abc import Callable
from pathlib import Path

import pytest
import yaml
from test_package import console_scripts, setup_kwargs

from conftest import ROOT

PKG = 'inertia_ros'
LAUNCH_FILES = ('estimator.launch.xml', 'sim.launch.xml', 'replay.launch.xml',
                'active.launch.xml')
#: Parameters every rclpy node has without declaring them.
STANDARD_PARAMETERS = {'use_sim_time': False}
#: Node-relative topic names each executable subscribes or publishes (README, DESIGN.md): the
#: names a launch file may remap.
NODE_TOPICS = {
    'inertia_estimator': {'imu', 'omega', 'torque'},
    'scene_simulator': {'imu', 'omega', 'torque'},
    'bag_player': {'imu', 'omega', 'torque'},
    'exciter': {'imu', 'torque_command'},
}
#: Attributes the launch XML front end accepts on each tag used here (launch, launch_ros).
TAG_ATTRIBUTES = {
    'arg': {'name', 'default', 'description', 'value'},  # value: in <include>
    'node': {'pkg', 'exec', 'name', 'namespace', 'output', 'args', 'ros_args'},
    'param': {'name', 'value', 'from'},
    'remap': {'from', 'to'},
    'include': {'file'},
}
SUBSTITUTION = re.compile(r'\$\(([\w-]+)(?: ([^)]*))?\)')


def installed_files() -> dict[str, Path]:
    """Installed path (relative to the install prefix) -> source file, from setup.py's
    data_files (the globs evaluated as colcon does, in the source tree)."""
    out: dict[str, Path] = {}
    for dest, sources in setup_kwargs()['data_files']:
        for src in sources:
            out[f'{dest}/{Path(src).name}'] = ROOT / src
    return out


def source_share(rel: str) -> Path | None:
    """Source file installed as ``share/inertia_ros/<rel>``, or None when nothing is."""
    return installed_files().get(f'share/{PKG}/{rel}')


def parameter_table(executable: str) -> dict[str, object]:
    """Name -> default of every parameter of a node, from ``config/<executable>.yaml``."""
    doc = yaml.safe_load((ROOT / 'config' / f'{executable}.yaml').read_text())
    return {**STANDARD_PARAMETERS, **doc[executable]['ros__parameters']}


class LaunchFile:
    """A parsed launch file with its arguments resolved (defaults, or the includer's)."""

    def __init__(self, path: Path, given: dict[str, str] | None = None) -> None:
        self.path = path
        self.root = ET.parse(path).getroot()
        self.args = {a.get('name'): a for a in self.root if a.tag == 'arg'}
        self.given = dict(given or {})

    def value(self, name: str) -> str | None:
        """An argument's value: given by the includer, else its default (None: required)."""
        if name in self.given:
            return self.given[name]
        return self.args[name].get('default')


def resolve(text: str, lf: LaunchFile, share: Callable[[str], Path | None]) -> str | None:
    """Apply ``$(var NAME)`` and ``$(find-pkg-share inertia_ros)`` to ``text``.

    ``share(rel)`` maps a path below ``share/inertia_ros`` to a real file (source tree or an
    install prefix).  Returns None when the text depends on a required argument.
    """
    def sub(m: re.Match) -> str:
        kind, arg = m.group(1), (m.group(2) or '').strip()
        if kind == 'var':
            assert arg in lf.args, f'{lf.path.name}: $(var {arg}) is not a declared <arg>'
            val = lf.value(arg)
            if val is None:
                raise LookupError(arg)
            return resolve(val, lf, share) or ''
        if kind == 'find-pkg-share':
            assert arg == PKG, f'{lf.path.name}: $(find-pkg-share {arg}): not this package'
            return f'<share>/{PKG}'
        raise AssertionError(f'{lf.path.name}: unsupported substitution $({kind} ...)')

    try:
        return SUBSTITUTION.sub(sub, text)
    except LookupError:
        return None


def resolve_file(text: str, lf: LaunchFile, share: Callable[[str], Path | None]) -> Path:
    """A file path attribute, resolved and required to exist in the share layout."""
    value = resolve(text, lf, share)
    assert value is not None and value.startswith(f'<share>/{PKG}/'), \
        f'{lf.path.name}: {text!r} must resolve to a file of share/{PKG}'
    rel = value.removeprefix(f'<share>/{PKG}/')
    path = share(rel)
    assert path is not None and path.is_file(), \
        f'{lf.path.name}: {text!r} -> share/{PKG}/{rel} is not installed'
    return path


def _check_value(lf: LaunchFile, exe: str, name: str, value: str | None,
                 default: object) -> None:
    """A parameter value (a YAML scalar, as launch_ros reads it) has the declared type."""
    if value is None:  # from a required argument: typed by the user
        return
    parsed = yaml.safe_load(value) if value != '' else ''
    want = type(default)
    ok = isinstance(parsed, want) and not (want is int and isinstance(parsed, bool))
    assert ok, (f'{lf.path.name}: {exe} parameter {name}={value!r} is a '
                f'{type(parsed).__name__}, declared {want.__name__} (default {default!r})')


def check_launch_file(path: Path, share: Callable[[str], Path | None],
                      given: dict[str, str] | None = None) -> list[str]:
    """Every check of the module docstring on one launch file (and what it includes).

    Returns the executables it starts, includes included.
    """
    lf = LaunchFile(path, given)
    assert lf.root.tag == 'launch', f'{path.name}: root element is <{lf.root.tag}>'
    scripts = console_scripts()
    started: list[str] = []
    for el in lf.root.iter():
        if el.tag in TAG_ATTRIBUTES:
            extra = set(el.attrib) - TAG_ATTRIBUTES[el.tag]
            assert not extra, f'{path.name}: <{el.tag}> has unknown attributes {extra}'
    for name, arg in lf.args.items():
        assert arg.get('description'), f'{path.name}: <arg {name}> has no description'
    for el in lf.root:
        if el.tag == 'arg':
            continue
        if el.tag == 'include':
            inc = resolve_file(el.get('file'), lf, share)
            passed = {a.get('name'): resolve(a.get('value'), lf, share) or ''
                      for a in el.iter('arg')}
            declared = LaunchFile(inc).args
            unknown = set(passed) - set(declared)
            assert not unknown, f'{path.name}: {inc.name} declares no argument {unknown}'
            needed = {n for n, a in declared.items() if a.get('default') is None}
            assert needed <= set(passed), f'{path.name}: {inc.name} needs {needed - set(passed)}'
            started += check_launch_file(inc, share, passed)
            continue
        assert el.tag == 'node', f'{path.name}: unexpected <{el.tag}>'
        pkg, exe = el.get('pkg'), el.get('exec')
        assert pkg == PKG, f'{path.name}: node of package {pkg!r}'
        assert exe in scripts, f'{path.name}: exec {exe!r} is not a console script of setup.py'
        # The parameter files are keyed by the node name: keep it the executable's name.
        assert el.get('name') == exe, f'{path.name}: node {exe} named {el.get("name")!r}'
        table = parameter_table(exe)
        for p in el.iter('param'):
            if p.get('from') is not None:
                params = yaml.safe_load(resolve_file(p.get('from'), lf, share).read_text())
                assert exe in params, f'{path.name}: {p.get("from")} has no {exe}: section'
                unknown = set(params[exe]['ros__parameters']) - set(table)
                assert not unknown, f'{path.name}: unknown {exe} parameters {unknown}'
                continue
            name, value = p.get('name'), resolve(p.get('value'), lf, share)
            assert name in table, f'{path.name}: {exe} has no parameter {name!r}'
            _check_value(lf, exe, name, value, table[name])
            if value is not None and value.startswith('<share>/'):
                resolve_file(p.get('value'), lf, share)  # a file parameter: it must exist
        for r in el.iter('remap'):
            assert r.get('from') in NODE_TOPICS[exe], \
                f'{path.name}: {exe} uses no topic {r.get("from")!r}'
            assert resolve(r.get('to'), lf, share), f'{path.name}: empty remap target'
        started.append(exe)
    return started


def test_launch_files_are_the_documented_four():
    """launch/ holds the estimator, simulation, replay and active launch files, all installed."""
    assert sorted(p.name for p in (ROOT / 'launch').glob('*.launch.xml')) == \
        sorted(LAUNCH_FILES)
    for name in LAUNCH_FILES:
        assert source_share(f'launch/{name}') == ROOT / 'launch' / name


@pytest.mark.parametrize('name, starts', [
    ('estimator.launch.xml', ['inertia_estimator']),
    ('sim.launch.xml', ['inertia_estimator', 'scene_simulator']),
    ('replay.launch.xml', ['inertia_estimator', 'bag_player']),
    ('active.launch.xml', ['inertia_estimator', 'scene_simulator', 'exciter']),
])
def test_launch_file_names_only_what_exists(name, starts):
    """Executables, parameters (name and type), remaps, arguments and files all exist."""
    assert check_launch_file(ROOT / 'launch' / name, source_share) == starts


def _args(name: str) -> dict[str, ET.Element]:
    return LaunchFile(ROOT / 'launch' / name).args


def test_launch_arguments():
    """The estimator's params file and input topics are arguments; replay runs it on sim time
    and needs the bag; sim and replay start it through the one estimator.launch.xml."""
    est = _args('estimator.launch.xml')
    assert {'params_file', 'imu', 'omega', 'torque', 'use_sim_time'} <= set(est)
    assert all(a.get('default') is not None for a in est.values())
    replay = LaunchFile(ROOT / 'launch' / 'replay.launch.xml')
    assert replay.value('bag') is None  # required
    assert replay.value('use_sim_time') == 'true'
    inc = replay.root.find('include')
    assert {a.get('name'): a.get('value') for a in inc.iter('arg')}['use_sim_time'] == \
        '$(var use_sim_time)'
    assert LaunchFile(ROOT / 'launch' / 'estimator.launch.xml').value('use_sim_time') == 'false'


def test_checker_catches_mistakes(tmp_path):
    """The static checks fail on an unknown executable, parameter, type, remap, file or arg."""
    good = (ROOT / 'launch' / 'sim.launch.xml').read_text()
    cases = {
        'exec="scene_simulator"': ('exec="scene_sim"', 'not a console script'),
        '<param name="rate"': ('<param name="speed"', 'no parameter'),
        'default="1.0"': ('default="1"', 'is a int, declared float'),
        'value="$(var seed)"': ('value="$(var sed)"', 'not a declared <arg>'),
        'config/scene_simulator.yaml': ('config/scene_sim.yaml', 'is not installed'),
        'scenes/default.yaml': ('scenes/nope.yaml', 'is not installed'),
        '<arg name="params_file" value=': ('<arg name="param_file" value=',
                                           'declares no argument'),
    }
    for old, (new, message) in cases.items():
        assert old in good
        bad = tmp_path / 'bad.launch.xml'
        bad.write_text(good.replace(old, new))
        with pytest.raises(AssertionError, match=re.escape(message)):
            check_launch_file(bad, source_share)
    est = (ROOT / 'launch' / 'estimator.launch.xml').read_text()
    bad.write_text(est.replace('<remap from="imu"', '<remap from="gyro"'))
    with pytest.raises(AssertionError, match='uses no topic'):
        check_launch_file(bad, source_share)


# --- visualisation configurations -------------------------------------------------------------

def estimator_publications() -> dict[str, str]:
    """Topic -> message class (``pkg.msg.Type``) of every ``create_publisher`` call of the
    estimator node (its module and its outputs module) with a literal topic, ``~/`` expanded
    with the default node name."""
    out = {}
    for name in ('estimator.py', 'outputs.py'):
        out.update(_publications(ROOT / 'inertia_ros' / 'nodes' / name))
    return out


def _publications(path) -> dict[str, str]:
    """Topic -> message class of the ``create_publisher`` calls of one module."""
    tree = ast.parse(path.read_text())
    modules = {a.asname or a.name: n.module for n in ast.walk(tree)
               if isinstance(n, ast.ImportFrom) and n.module for a in n.names}
    out = {}
    for n in ast.walk(tree):
        if (isinstance(n, ast.Call) and isinstance(n.func, ast.Attribute)
                and n.func.attr == 'create_publisher' and len(n.args) >= 2
                and isinstance(n.args[0], ast.Name) and isinstance(n.args[1], ast.Constant)):
            topic = str(n.args[1].value)
            topic = '/inertia_estimator/' + topic[2:] if topic.startswith('~/') else topic
            out[topic] = f'{modules[n.args[0].id]}.{n.args[0].id}'
    return out


def _field_type(msg_class: str, fields: list[str]) -> str:
    """ROS type of a dotted field path of a message class (imports the interface package)."""
    import importlib

    module, name = msg_class.rsplit('.', 1)
    cls = getattr(importlib.import_module(module), name)
    for i, field in enumerate(fields):
        types = cls.get_fields_and_field_types()
        assert field in types, f'{msg_class} has no field {".".join(fields[:i + 1])}'
        kind = types[field]
        if '/' in kind:
            pkg, typ = kind.split('/')
            cls = getattr(importlib.import_module(f'{pkg}.msg'), typ)
    return kind


def test_estimator_publications_match_the_design():
    """The scan finds the documented outputs, each named in docs/DESIGN.md."""
    pubs = estimator_publications()
    assert pubs['/inertia_estimator/markers'] == 'visualization_msgs.msg.MarkerArray'
    assert pubs['/inertia_estimator/principal_moments'] == 'geometry_msgs.msg.Vector3Stamped'
    assert pubs['/diagnostics'] == 'diagnostic_msgs.msg.DiagnosticArray'
    design = (ROOT / 'docs' / 'DESIGN.md').read_text()
    for topic in pubs:
        short = topic.replace('/inertia_estimator/', '~/')
        assert f'`{short}`' in design, f'{short} not documented in docs/DESIGN.md'


def test_rviz_config():
    """inertia_ros.rviz is RViz2 YAML: a MarkerArray display on the estimator's markers, TF,
    a grid, the body frame as Fixed Frame; every topic it names is an estimator output of
    the display's message type."""
    path = ROOT / 'config' / 'inertia_ros.rviz'
    assert source_share('config/inertia_ros.rviz') == path
    doc = yaml.safe_load(path.read_text())
    vm = doc['Visualization Manager']
    assert vm['Global Options']['Fixed Frame'] == 'base_link'
    displays = {d['Class']: d for d in vm['Displays']}
    assert {'rviz_default_plugins/MarkerArray', 'rviz_default_plugins/TF',
            'rviz_default_plugins/Grid'} <= set(displays)
    assert displays['rviz_default_plugins/MarkerArray']['Topic']['Value'] == \
        '/inertia_estimator/markers'
    pubs = estimator_publications()
    display_types = {'rviz_default_plugins/MarkerArray': 'visualization_msgs.msg.MarkerArray'}
    for d in vm['Displays']:
        topic = d.get('Topic', {}).get('Value')
        if topic is not None:
            assert topic in pubs, f'{path.name}: {d["Name"]} shows {topic}, never published'
            assert pubs[topic] == display_types[d['Class']]


def _strings(obj) -> list[str]:
    if isinstance(obj, dict):
        return [s for k, v in obj.items() for s in _strings(k) + _strings(v)]
    if isinstance(obj, list):
        return [s for v in obj for s in _strings(v)]
    return [obj] if isinstance(obj, str) else []


def test_foxglove_layout():
    """foxglove_layout.json: a 3D panel with the markers, a plot of the three principal
    moments over time and the diagnostics panels; every topic (and message path) it names
    is an estimator output with that field, and every panel is placed in the layout."""
    path = ROOT / 'config' / 'foxglove_layout.json'
    assert source_share('config/foxglove_layout.json') == path
    doc = json.loads(path.read_text())
    panels = doc['configById']
    kinds = {pid.split('!')[0]: cfg for pid, cfg in panels.items()}
    assert set(kinds) == {'3D', 'Plot', 'DiagnosticSummary', 'DiagnosticStatusPanel'}
    assert kinds['3D']['topics'] == {'/inertia_estimator/markers': {'visible': True}}
    assert kinds['3D']['followTf'] == 'base_link'
    assert [p['value'] for p in kinds['Plot']['paths']] == [
        f'/inertia_estimator/principal_moments.vector.{c}' for c in 'xyz']
    assert kinds['Plot']['xAxisVal'] == 'timestamp'
    assert kinds['DiagnosticSummary']['topicToRender'] == '/diagnostics'
    assert kinds['DiagnosticStatusPanel']['topicToRender'] == '/diagnostics'
    placed = {s for s in _strings(doc['layout']) if '!' in s}
    assert placed == set(panels), f'panels not in the layout: {set(panels) - placed}'
    pubs = estimator_publications()
    for s in _strings(doc['configById']):
        if s.startswith('/'):
            topic = s.split('.')[0]
            assert topic in pubs, f'{path.name}: {s} names a topic the estimator never publishes'


def test_foxglove_message_paths_exist():
    """Every message path of the layout (topic.field.field) is a float64 field of the
    message type the estimator publishes on that topic."""
    pytest.importorskip('geometry_msgs.msg')
    doc = json.loads((ROOT / 'config' / 'foxglove_layout.json').read_text())
    pubs = estimator_publications()
    paths = [s for s in _strings(doc['configById']) if s.startswith('/') and '.' in s]
    assert len(paths) == 3
    for s in paths:
        topic, *fields = s.split('.')
        assert _field_type(pubs[topic], fields) == 'double', s
    with pytest.raises(AssertionError, match='has no field vector.w'):
        _field_type(pubs['/inertia_estimator/principal_moments'], ['vector', 'w'])


def test_active_launch_passes_a_wheels_file_to_the_exciter():
    """active.launch.xml's ``wheels`` argument (default '': no wheels) is the exciter's
    ``wheels`` parameter."""
    lf = LaunchFile(ROOT / 'launch' / 'active.launch.xml')
    assert lf.value('wheels') == ''
    exciter = next(n for n in lf.root.iter('node') if n.get('exec') == 'exciter')
    params = {p.get('name'): p.get('value') for p in exciter.iter('param') if p.get('name')}
    assert params['wheels'] == '$(var wheels)'
