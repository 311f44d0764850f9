"""package.xml is a valid format-3 ament_python manifest declaring what the code uses.

Every third-party top-level module imported by ``inertia_ros/`` (installed code: an
``exec_depend``) or ``test/`` (an ``exec_depend`` or ``test_depend``) maps to a rosdep key in
:data:`IMPORT_KEYS`, and every key package.xml declares is needed by an import or by a
non-import use listed in :data:`NON_IMPORT_KEYS`.  The keys are those of rosdistro's rosdep
database (ROS packages by name; ``rosdep/python.yaml`` for Python packages, ``-pip`` keys
where no distribution package exists).
"""
from __future__ import annotations

import ast
import functools
import os
import re
import sys
from pathlib import Path

import pytest

from conftest import ROOT

#: Top-level import name -> rosdep key that provides it.
IMPORT_KEYS: dict[str, str] = {
    'rclpy': 'rclpy',
    'rcl_interfaces': 'rcl_interfaces',
    'ament_index_python': 'ament_index_python',
    'builtin_interfaces': 'builtin_interfaces',
    'std_msgs': 'std_msgs',
    'geometry_msgs': 'geometry_msgs',
    'sensor_msgs': 'sensor_msgs',
    'diagnostic_msgs': 'diagnostic_msgs',
    'visualization_msgs': 'visualization_msgs',
    'std_srvs': 'std_srvs',
    'rosgraph_msgs': 'rosgraph_msgs',
    'numpy': 'python3-numpy',
    'scipy': 'python3-scipy',
    'yaml': 'python3-yaml',
    'matplotlib': 'python3-matplotlib',
    'tqdm': 'python3-tqdm',
    'threadpoolctl': 'python3-threadpoolctl',
    # rosdistro has no key for the Python mcap package nor for its chunk codecs: the
    # mcap-ros2-support pip key installs mcap, which requires zstandard and lz4.
    'mcap': 'mcap-ros2-support',
    'zstandard': 'mcap-ros2-support',
    'lz4': 'mcap-ros2-support',
    'mcap_ros2': 'mcap-ros2-support',
    'pytest': 'python3-pytest',
    'hypothesis': 'python3-hypothesis',
    'catkin_pkg': 'python3-catkin-pkg',
    'rosbags': 'python3-rosbags-pip',
    'ruff': 'python3-ruff-pip',
    'urdf_parser_py': 'urdfdom_py',
    'setuptools': 'python3-setuptools',
    # the fleet command: pip keys of rosdep/inertia_ros.yaml (rosdistro has none)
    'dask': 'python3-dask-pip',
    'distributed': 'python3-distributed-pip',
    'pyarrow': 'python3-pyarrow-pip',
    # fsspec is a requirement of dask itself
    'fsspec': 'python3-dask-pip',
}

#: Declared keys that no import reaches, and what needs them.
NON_IMPORT_KEYS: dict[str, str] = {
    'ros2launch': 'launch/*.launch.xml are run with ros2 launch (XML front end)',
    'python3-pytest-timeout': "pyproject.toml's [tool.pytest.ini_options] timeout",
}

#: Imports that are optional by design: guarded at run time, with a note when absent.
OPTIONAL_IMPORTS: dict[str, str] = {
    'pinocchio': 'inertia_ros/bench/methods.py: the peer baseline of make bench '
                 '(requirements-bench.txt), skipped with a note when not importable',
    # the fleet command: declared (rosdep/inertia_ros.yaml keys), yet imported only by fleet,
    # with a one-line error when absent
    'distributed': 'inertia_ros/fleet/cluster.py: Dask for python -m inertia_ros fleet',
    'pyarrow': 'inertia_ros/fleet/table.py: Parquet tables of fleet (CSV without it)',
    'fsspec': 'inertia_ros/fleet/discover.py: fleet on URLs (s3://, ...)',
}


def _pkg():
    """package.xml parsed by catkin_pkg (the parser colcon and rosdep use)."""
    catkin = pytest.importorskip('catkin_pkg.package')  # optional test dependency
    return catkin.parse_package(str(ROOT / 'package.xml'))


def _first_party() -> set[str]:
    """Module names that belong to this repository (the package, test modules, conftest)."""
    names = {'inertia_ros', 'conftest'}
    names |= {p.stem for p in (ROOT / 'test').glob('*.py')}
    return names


def imported_modules(path: Path) -> set[str]:
    """Top-level names of every module a Python file imports.

    Statements ``import a.b`` and ``from a.b import c`` (absolute) anywhere in the file, plus
    string literals given to ``pytest.importorskip`` and ``importlib.import_module``.
    """
    tree = ast.parse(path.read_text(), filename=str(path))
    names: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names |= {a.name.split('.')[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names.add(node.module.split('.')[0])
        elif (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
              and node.func.attr in ('importorskip', 'import_module') and node.args
              and isinstance(node.args[0], ast.Constant)
              and isinstance(node.args[0].value, str)):
            names.add(node.args[0].value.split('.')[0])
    return names


def third_party_imports(folder: str) -> dict[str, list[str]]:
    """Third-party top-level module -> files under ``folder`` (or the file) importing it."""
    skip = set(sys.stdlib_module_names) | _first_party() | {'__future__'}
    found: dict[str, list[str]] = {}
    top = ROOT / folder
    for path in sorted(top.rglob('*.py') if top.is_dir() else [top]):
        for name in imported_modules(path) - skip:
            found.setdefault(name, []).append(str(path.relative_to(ROOT)))
    return found


def test_package_xml_parses_and_validates():
    """catkin_pkg parses package.xml and its validate() raises nothing."""
    pkg = _pkg()
    pkg.validate()
    assert pkg.name == 'inertia_ros'
    assert pkg.package_format == 3


def test_build_type_is_ament_python():
    """The export declares ament_python, so colcon treats the package as ros.ament_python."""
    assert _pkg().get_build_type() == 'ament_python'


def test_import_scan_sees_known_imports(tmp_path):
    """The scanner finds plain, dotted, from-, nested and importorskip imports, not relatives."""
    src = tmp_path / 'm.py'
    src.write_text('import os, numpy.linalg as la\nfrom scipy import optimize\n'
                   'from . import sibling\n'
                   'def f():\n    import yaml\n    pytest.importorskip("rosbags.typesys")\n'
                   '    importlib.import_module("mcap_ros2.decoder")\n')
    assert imported_modules(src) == {'os', 'numpy', 'scipy', 'yaml', 'rosbags', 'mcap_ros2'}
    assert {'numpy', 'rclpy', 'yaml'} <= set(third_party_imports('inertia_ros'))


def _keys(*groups) -> set[str]:
    return {d.name for g in groups for d in g}


@pytest.mark.parametrize('folder', ['inertia_ros', 'test', 'setup.py'])
def test_every_import_has_a_declared_rosdep_key(folder):
    """Each third-party import maps to a key package.xml declares: installed code needs an
    exec_depend (it runs on the robot), setup.py a build(tool)_depend, tests any of them or
    a test_depend."""
    pkg = _pkg()
    run = _keys(pkg.exec_depends)
    build = _keys(pkg.buildtool_depends, pkg.build_depends)
    allowed = {'inertia_ros': run, 'setup.py': build,
               'test': run | build | _keys(pkg.test_depends)}[folder]
    found = third_party_imports(folder)
    unmapped = {m: f for m, f in found.items() if m not in IMPORT_KEYS and m not in
                OPTIONAL_IMPORTS}
    assert not unmapped, (f'imports without a rosdep key in IMPORT_KEYS: {unmapped}; add the '
                          'rosdistro key here and to package.xml')
    missing = {m: (IMPORT_KEYS[m], f) for m, f in found.items()
               if m in IMPORT_KEYS and IMPORT_KEYS[m] not in allowed}
    assert not missing, f'package.xml lacks a dependency ({folder}) for: {missing}'


def test_every_declared_key_is_used():
    """No stale dependency: each declared key is reached by an import or a listed non-import
    use (ament_flake8, never run, was one)."""
    pkg = _pkg()
    declared = {d.name for d in pkg.exec_depends + pkg.test_depends + pkg.build_depends
                + pkg.build_export_depends + pkg.buildtool_depends}
    imported = {m for folder in ('inertia_ros', 'test', 'setup.py')
                for m in third_party_imports(folder)}
    reached = {IMPORT_KEYS[m] for m in imported if m in IMPORT_KEYS} | set(NON_IMPORT_KEYS)
    assert declared - reached == set(), f'declared but unused: {sorted(declared - reached)}'
    assert 'ament_flake8' not in declared


#: The keys rosdep/inertia_ros.yaml adds to rosdistro's database.
LOCAL_ROSDEP = ROOT / 'rosdep' / 'inertia_ros.yaml'


def test_local_rosdep_keys_are_declared_pinned_and_documented():
    """Each key of rosdep/inertia_ros.yaml is a pip key (debian, ubuntu, osx) that package.xml
    declares, whose pip package requirements.txt pins; the README registers the file."""
    import yaml

    rules = yaml.safe_load(LOCAL_ROSDEP.read_text())
    assert set(rules) == {'python3-dask-pip', 'python3-distributed-pip', 'python3-pyarrow-pip'}
    declared = {d.name for d in _pkg().exec_depends}
    pins = dict(re.findall(r'^([A-Za-z0-9_.-]+)==(\S+)', (ROOT / 'requirements.txt').read_text(),
                           re.M))
    for key, rule in rules.items():
        assert key in declared, f'{key} defined in {LOCAL_ROSDEP.name} but not in package.xml'
        assert set(rule) == {'debian', 'ubuntu', 'osx'}, key
        for os_name, installers in rule.items():
            (packages,) = [installers['pip']['packages']]
            assert packages == [key.removeprefix('python3-').removesuffix('-pip')], (key, os_name)
            assert packages[0] in pins, f'{packages[0]} is not pinned in requirements.txt'
    readme = (ROOT / 'README.md').read_text()
    assert 'rosdep/inertia_ros.yaml' in readme and 'sources.list.d' in readme


def test_optional_imports_are_guarded():
    """An optional import only ever appears inside a function, under try/except ImportError."""
    for name, where in OPTIONAL_IMPORTS.items():
        path = ROOT / where.split(':')[0]
        tree = ast.parse(path.read_text())
        top = {a.name.split('.')[0] for n in tree.body if isinstance(n, ast.Import)
               for a in n.names}
        top |= {n.module.split('.')[0] for n in tree.body
                if isinstance(n, ast.ImportFrom) and n.module}
        assert name not in top, f'{path}: {name} imported at module level'
        assert re.search(rf'try:\s*\n\s*import {name}\b', path.read_text()), \
            f'{path}: import {name} is not guarded by try'


def test_license_file_and_maintainer():
    """LICENSE holds the Apache-2.0 text package.xml and setup.py name; the maintainer is a
    real address, not a placeholder domain."""
    pkg = _pkg()
    assert [str(lic) for lic in pkg.licenses] == ['Apache-2.0']
    assert pkg.licenses[0].file == 'LICENSE'
    text = (ROOT / 'LICENSE').read_text()
    assert 'Apache License' in text and 'Version 2.0, January 2004' in text
    assert 'END OF TERMS AND CONDITIONS' in text
    setup = (ROOT / 'setup.py').read_text()
    assert "license='Apache-2.0'" in setup
    (maintainer,) = pkg.maintainers
    assert maintainer.name == 'inertia_ros maintainers'
    assert re.fullmatch(r'[\w.+-]+@[\w-]+(\.[\w-]+)+', maintainer.email)
    assert not re.search(r'example\.(com|org|net)$|\.example$|\.invalid$|\.test$',
                         maintainer.email), maintainer.email
    assert f"maintainer_email='{maintainer.email}'" in setup


def test_setup_py_version_matches_package_xml():
    """setup.py and package.xml carry the same version."""
    text = (ROOT / 'setup.py').read_text()
    m = re.search(r"version='([^']+)'", text)
    assert m and m.group(1) == _pkg().version


@functools.lru_cache(maxsize=1)
def setup_kwargs() -> dict:
    """The keyword arguments setup.py gives ``setuptools.setup`` (nothing is built; cached,
    do not modify)."""
    import runpy

    import setuptools

    captured: dict = {}
    real, cwd = setuptools.setup, os.getcwd()
    setuptools.setup = lambda **kwargs: captured.update(kwargs)
    os.chdir(ROOT)  # setup.py's globs are relative to the source tree, as colcon runs it
    try:
        runpy.run_path(str(ROOT / 'setup.py'), run_name='__main__')
    finally:
        setuptools.setup = real
        os.chdir(cwd)
    return captured


def console_scripts() -> dict[str, str]:
    """``name -> module:function`` of setup.py's console_scripts."""
    entries = setup_kwargs()['entry_points']['console_scripts']
    return dict(re.fullmatch(r'\s*([\w-]+)\s*=\s*([\w.]+:\w+)\s*', e).groups() for e in entries)


def test_test_extra_makes_colcon_use_pytest():
    """colcon picks its pytest step when pytest is in the test extra (else unittest, 0 tests;
    test_colcon.py runs it); the extra names the test tools package.xml declares."""
    extra = setup_kwargs()['extras_require']['test']
    assert {'pytest', 'pytest-timeout', 'hypothesis', 'rosbags', 'mcap-ros2-support',
            'ruff'} <= set(extra)


def test_console_scripts_resolve():
    """Every console script names an importable main (the nodes need rclpy to import, so
    their modules are checked by name); the offline CLI is ``inertia-ros``."""
    import importlib

    scripts = console_scripts()
    assert scripts['inertia-ros'] == 'inertia_ros.cli:main'
    assert {'inertia_estimator', 'scene_simulator', 'bag_player'} <= set(scripts)
    for target in scripts.values():
        module, func = target.split(':')
        assert (ROOT / (module.replace('.', '/') + '.py')).is_file() or \
            (ROOT / module.replace('.', '/') / '__init__.py').is_file(), target
    cli = importlib.import_module('inertia_ros.cli')
    assert callable(cli.main)
