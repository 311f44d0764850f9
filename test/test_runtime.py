"""The programs' memory setting: repeated estimates reuse freed heap instead of page-faulting
it in again (``inertia_ros.runtime.keep_freed_memory``)."""
from __future__ import annotations

import os
import platform
import subprocess
import sys

import pytest

from conftest import ROOT

GLIBC = platform.system() == 'Linux' and platform.libc_ver()[0] == 'glibc'

# five default (ml) estimates of the nominal 60 s record after two warm-up calls: minor page
# faults per estimate, with or without the setting
_FAULTS = """
import resource, sys
from inertia_ros.bench.common import nominal_scene
from inertia_ros.core.estimation import estimate
from inertia_ros.core.simulation import simulate
from inertia_ros.runtime import keep_freed_memory
if sys.argv[1] == 'keep':
    assert keep_freed_memory()
sim = simulate(nominal_scene(60.0), seed=1)
args = (sim.t_gyro, sim.omega, sim.t_torque, sim.torque)
for _ in range(2):
    estimate(*args)
f0 = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
for _ in range(5):
    assert estimate(*args).method == 'ml'
print((resource.getrusage(resource.RUSAGE_SELF).ru_minflt - f0) / 5)
"""


def _faults_per_estimate(mode: str) -> float:
    env = {k: v for k, v in os.environ.items() if not k.startswith('MALLOC_')}
    proc = subprocess.run([sys.executable, '-c', _FAULTS, mode], capture_output=True,
                          text=True, cwd=ROOT, env=env, check=False)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return float(proc.stdout.split()[-1])


@pytest.mark.skipif(not GLIBC, reason='the setting is glibc malloc only')
def test_repeated_ml_estimates_do_not_fault_their_arrays_in_again() -> None:
    """With the setting, an ``ml`` estimate of a 60 s record page-faults fewer than 100 times
    (its arrays come from kept heap); without it, over 10x as often (the control: the setting
    is what makes the difference; about 4000 faults, a fifth of the estimate's time)."""
    kept = _faults_per_estimate('keep')
    plain = _faults_per_estimate('plain')
    assert kept < 100, kept
    assert plain > 10 * max(kept, 100), (plain, kept)


def test_setting_is_once_per_process_and_the_environment_wins() -> None:
    """A user's ``MALLOC_TOP_PAD_`` stands (no call is made, False); without it the first call
    sets the pad and later calls return the same answer."""
    code = ('from inertia_ros.runtime import keep_freed_memory as k\n'
            'print(k(), k(), k(0))')
    env = {k: v for k, v in os.environ.items() if not k.startswith('MALLOC_')}
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         cwd=ROOT, env=env, check=True).stdout.split()
    assert out == ([str(GLIBC)] * 3)
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         cwd=ROOT, env=dict(env, MALLOC_TOP_PAD_='0'), check=True).stdout.split()
    assert out == ['False'] * 3


def test_cli_asks_for_the_setting(monkeypatch: pytest.MonkeyPatch, tmp_path) -> None:
    """Every command of the CLI (and so every fleet worker, which runs it) sets it before
    running; a parse error or ``--help`` does not."""
    import inertia_ros.cli as cli

    calls: list[int] = []
    monkeypatch.setattr(cli, 'keep_freed_memory', lambda: calls.append(1) or True)
    assert cli.main(['estimate', '--help']) == 0
    assert calls == []
    assert cli.main(['estimate', str(tmp_path / 'absent.mcap')]) == 2
    assert calls == [1]
