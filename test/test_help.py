"""Every ``--help`` a user can ask for answers: each command and sub-command of the command
line, the installed console scripts and each node executable print their usage and exit 0,
never a traceback (issue 29: ``fleet --help`` crashed and no test ran it)."""
from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import ROOT
from inertia_ros.cli import COMMANDS, build_parser

#: The node executables: module, console script (``ros2 run inertia_ros NAME``), read from
#: setup.py's console_scripts (every ``NAME = inertia_ros.X_node:main``).
NODES = tuple((m, name) for name, m in re.findall(
    r"'(\w+) = (inertia_ros\.\w+_node):main'", (ROOT / 'setup.py').read_text()))


def _sub_commands(parser: argparse.ArgumentParser, prefix: tuple[str, ...] = ()
                  ) -> list[tuple[str, ...]]:
    """Every command path below ``parser`` (``('bench',)``, ``('bench', 'offline')``, ...)."""
    out: list[tuple[str, ...]] = []
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                out.append((*prefix, name))
                out += _sub_commands(sub, (*prefix, name))
    return out


def _commands() -> list[tuple[str, ...]]:
    """Each command of :data:`COMMANDS` and every sub-command under it (from the parsers, so
    a new one is covered without editing this test)."""
    found: list[tuple[str, ...]] = []
    for name in COMMANDS:
        found.append((name,))
        try:
            parser = build_parser(name)
        except Exception:              # a parser that cannot even be built: its --help fails
            continue
        found += [p for p in _sub_commands(parser) if p[0] == name and len(p) > 1]
    return found


def _run(argv: list[str]) -> subprocess.CompletedProcess:
    env = dict(os.environ, MPLBACKEND='Agg')
    return subprocess.run(argv, capture_output=True, text=True, cwd=ROOT, check=False,
                          timeout=120, env=env)


def _check(proc: subprocess.CompletedProcess, usage: str) -> None:
    """Exit 0, the usage on stdout, no traceback anywhere."""
    assert 'Traceback' not in proc.stderr + proc.stdout, proc.stderr[-3000:]
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert proc.stdout.lstrip().lower().startswith(usage), proc.stdout[:300]


@pytest.mark.parametrize('path', _commands(), ids=' '.join)
def test_every_command_help(path: tuple[str, ...]) -> None:
    """``python -m inertia_ros COMMAND [SUB] --help`` prints its usage and exits 0 (fleet
    included)."""
    proc = _run([sys.executable, '-m', 'inertia_ros', *path, '--help'])
    _check(proc, 'usage: python -m inertia_ros ' + ' '.join(path))


def test_top_level_help() -> None:
    """``python -m inertia_ros --help`` lists every command."""
    proc = _run([sys.executable, '-m', 'inertia_ros', '--help'])
    _check(proc, 'usage: python -m inertia_ros')
    for name in COMMANDS:
        assert name in proc.stdout


@pytest.mark.parametrize('module', [m for m, _ in NODES])
def test_node_module_help(module: str) -> None:
    """``python -m inertia_ros.<x>_node --help`` prints the node's usage and exits 0."""
    _check(_run([sys.executable, '-m', module, '--help']), 'usage')


def _script(name: str) -> Path:
    """An installed console script next to this interpreter (skip when not installed)."""
    for folder in (Path(sys.executable).parent, Path(sys.prefix) / 'lib' / 'inertia_ros'):
        if (folder / name).exists():
            return folder / name
    pytest.skip(f'console script {name} not installed next to {sys.executable}')


@pytest.mark.parametrize('name', ['inertia-ros', *(s for _, s in NODES)])
def test_console_script_help(name: str) -> None:
    """The installed executables answer ``--help`` (``inertia-ros`` under its own name)."""
    proc = _run([str(_script(name)), '--help'])
    _check(proc, 'usage: inertia-ros' if name == 'inertia-ros' else 'usage')


def test_every_node_module_is_an_executable() -> None:
    """Each ``inertia_ros/*_node.py`` is a console script, so its ``--help`` is tested above."""
    modules = {f'inertia_ros.{p.stem}' for p in (ROOT / 'inertia_ros').glob('*_node.py')}
    assert modules == {m for m, _ in NODES} and len(NODES) >= 4


@pytest.mark.parametrize('argv', [['estimate', 'bags/default.mcap', '--model', 'x' * 100_000],
                                  ['fleet', 'bags', '--out', 'r.csv', '--workers', '9' * 5000],
                                  ['simulate', 'config/scenes/default.yaml', '--seed', 'a\nb']])
def test_a_bad_value_is_one_short_line(argv: list[str]) -> None:
    """argparse quotes an invalid value whole: the error stays one line of at most ~500
    characters, naming the option (issue 29: a 1 MB choice was echoed in full)."""
    proc = _run([sys.executable, '-m', 'inertia_ros', *argv])
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and len(lines[0]) < 520 and 'error: ' in lines[0], proc.stderr[:600]
    assert 'Traceback' not in proc.stderr
