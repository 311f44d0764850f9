"""Start-up of the command line: ``--help`` loads no numerical stack, ``--version``, one-line
parse errors."""
from __future__ import annotations

import subprocess
import sys

import pytest

from conftest import ROOT
from inertia_ros import __version__
from inertia_ros.cli import COMMANDS, main

HEAVY = ('numpy', 'scipy', 'matplotlib', 'mcap', 'yaml', 'rclpy')


def _imported(*argv: str) -> tuple[subprocess.CompletedProcess, set[str]]:
    """Run ``python -X importtime -m inertia_ros ARGV``; return the process and the top-level
    names of every module it imported."""
    proc = subprocess.run([sys.executable, '-X', 'importtime', '-m', 'inertia_ros', *argv],
                          capture_output=True, text=True, cwd=ROOT, check=False)
    names = set()
    for line in proc.stderr.splitlines():
        if line.startswith('import time:') and '|' in line:
            name = line.rsplit('|', 1)[1].strip()
            if name != 'imported package':
                names.add(name.split('.')[0])
    return proc, names


@pytest.mark.parametrize('command', ['estimate', 'simulate', 'bench'])
def test_command_help_imports_no_numerical_stack(command: str) -> None:
    """``COMMAND --help`` prints the usage and loads none of numpy/scipy/matplotlib/mcap."""
    proc, names = _imported(command, '--help')
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stdout.startswith('usage: python -m inertia_ros ' + command)
    assert 'inertia_ros' in names          # the parse really ran under -X importtime
    assert not names & set(HEAVY), sorted(names & set(HEAVY))


def test_integral_estimate_of_a_log_imports_no_scipy() -> None:
    """The estimate of a long log (the integral method) loads no scipy at all: its p-values
    are closed-form and its range sums numpy (scipy's base alone, which scipy.sparse pulls
    in, costs ~0.1 s of a whole process that has 0.9 s for an hour-long log); nor numpy.ma,
    the ml module or the stated- and momentum-input modules."""
    proc = subprocess.run([sys.executable, '-X', 'importtime', '-m', 'inertia_ros', 'estimate',
                           'bags/default.mcap', '--method', 'integral', '--format', 'json',
                           '--no-progress'], capture_output=True, text=True, cwd=ROOT,
                          check=False)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert '"status": "ok"' in proc.stdout
    names = {line.rsplit('|', 1)[1].strip() for line in proc.stderr.splitlines()
             if line.startswith('import time:') and '|' in line}
    assert 'numpy' in names
    assert not {n for n in names if n.split('.')[0] == 'scipy'}
    # nor numpy.ma (np.median and np.unique load it: ~7 ms), nor the ml refinement, nor the
    # stated-input and momentum-input modules (~8 ms)
    assert not {'numpy.ma', 'inertia_ros.core.estimation.ml', 'inertia_ros.core.estimation.stated',
                'inertia_ros.core.estimation.momentum'} & names


def test_momentum_input_estimate_imports_no_excitation_designer() -> None:
    """``estimate --rotors`` reads its actuator file without the excitation designer (its
    package imports ``scipy.optimize``: ~0.3 s of CPU, a quarter of the sample rotor log's
    whole process)."""
    proc = subprocess.run([sys.executable, '-X', 'importtime', '-m', 'inertia_ros', 'estimate',
                           'bags/quadrotor.mcap', '--rotors', 'bags/quadrotor_rotors.yaml',
                           '--format', 'json', '--no-progress'], capture_output=True,
                          text=True, cwd=ROOT, check=False)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert '"status":' in proc.stdout
    names = {line.rsplit('|', 1)[1].strip() for line in proc.stderr.splitlines()
             if line.startswith('import time:') and '|' in line}
    assert 'inertia_ros.io.rotors' in names
    assert not {'inertia_ros.core.excitation', 'scipy.optimize'} & names


def test_version_imports_no_numerical_stack() -> None:
    """``--version`` answers without loading any command module."""
    proc, names = _imported('--version')
    assert proc.returncode == 0 and proc.stdout == f'inertia_ros {__version__}\n'
    assert not names & set(HEAVY), sorted(names & set(HEAVY))


def test_estimate_help_lists_the_vocabularies() -> None:
    """The choices shown by ``estimate --help`` come from estimation.options."""
    from inertia_ros.core.estimation.options import METHODS, MODELS

    proc = subprocess.run([sys.executable, '-m', 'inertia_ros', 'estimate', '--help'],
                          capture_output=True, text=True, cwd=ROOT, check=False)
    flat = ' '.join(proc.stdout.split())
    assert '{' + ','.join(METHODS) + '}' in flat
    assert '{' + ','.join(MODELS) + '}' in flat
    assert '--torque-delay S' in flat and '|S| <= 10' in flat


def test_version_as_a_process() -> None:
    """``python -m inertia_ros --version`` prints the package version, exit 0."""
    proc = subprocess.run([sys.executable, '-m', 'inertia_ros', '--version'],
                          capture_output=True, text=True, cwd=ROOT, check=False)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout == f'inertia_ros {__version__}\n'
    assert proc.stderr == ''


def test_version_in_process(capsys: pytest.CaptureFixture) -> None:
    """``main(['--version'])`` exits 0 with the version from the package metadata."""
    assert main(['--version']) == 0
    assert capsys.readouterr().out.strip() == f'inertia_ros {__version__}'


def test_version_matches_the_installed_metadata() -> None:
    """``__version__`` is the version of the installed distribution (setup.py, package.xml)."""
    from importlib import metadata

    assert __version__ == metadata.version('inertia_ros')
    xml = (ROOT / 'package.xml').read_text()
    assert f'<version>{__version__}</version>' in xml


def test_top_level_help_lists_every_command(capsys: pytest.CaptureFixture) -> None:
    """``--help`` without a command names every command."""
    assert main(['--help']) == 0
    out = capsys.readouterr().out
    for name in COMMANDS:
        assert name in out


@pytest.mark.parametrize('argv, piece', [
    (['frobnicate'], "invalid choice: 'frobnicate'"),
    (['estimate'], 'the following arguments are required: PATH'),
    (['estimate', 'x.mcap', '--method', 'magic'], "argument --method: invalid choice"),
    (['simulate', 's.yaml', '-o', 'o.mcap', '--seed', '-1'], 'argument --seed'),
])
def test_parse_errors_are_one_line(argv: list[str], piece: str,
                                   capsys: pytest.CaptureFixture) -> None:
    """argparse's usage-plus-error becomes one line naming the option, exit status 2."""
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1, err
    assert piece in err and err.rstrip().endswith('(see --help)')
