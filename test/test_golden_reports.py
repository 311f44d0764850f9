"""The sample bags' JSON reports against saved ones: refactors must not change an answer.

The reports in ``test/data/golden/`` were written by ``estimate BAG --format json [--method M]``.
A deliberate change of behaviour regenerates them with
``INERTIA_REGEN_GOLDEN=1 python -m pytest test/test_golden_reports.py`` and says why in the
commit message.
"""
from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

from conftest import ROOT
from inertia_ros.cli import main

GOLDEN = ROOT / 'test' / 'data' / 'golden'
BAGS = ('default', 'torque_free', 'single_axis', 'disturbance')
METHODS = ('', 'integral', 'integral_ls', 'integral_sliding', 'differential_fd',
           'differential_sg', 'filtered')
#: Relative tolerance of a number: reordered floating-point sums, nothing more.
RTOL = 1e-9


def _compare(got: object, want: object, where: str) -> None:
    if isinstance(want, dict):
        assert isinstance(got, dict) and set(got) == set(want), (
            f'{where}: keys differ: {sorted(set(got) ^ set(want))}')
        for k in want:
            _compare(got[k], want[k], f'{where}.{k}')
    elif isinstance(want, list):
        assert isinstance(got, list) and len(got) == len(want), f'{where}: length differs'
        for i, (g, w) in enumerate(zip(got, want, strict=True)):
            _compare(g, w, f'{where}[{i}]')
    elif isinstance(want, float) and not isinstance(want, bool):
        assert isinstance(got, (int, float)), f'{where}: {got!r} is not a number'
        assert np.isclose(got, want, rtol=RTOL, atol=1e-15), f'{where}: {got!r} != {want!r}'
    else:
        assert got == want, f'{where}: {got!r} != {want!r}'


@pytest.mark.parametrize('method', METHODS)
@pytest.mark.parametrize('bag', BAGS)
def test_report_unchanged(bag: str, method: str, tmp_path: Path,
                          capsys: pytest.CaptureFixture) -> None:
    """The JSON report of a committed bag equals the saved one (numbers to 1e-9)."""
    log = ROOT / 'bags' / f'{bag}.mcap'
    if not log.exists():
        pytest.skip(f'{log} absent')
    name = f'{bag}_{method}.json' if method else f'{bag}.json'
    args = ['estimate', str(log), '--format', 'json', '--no-progress']
    if method:
        args += ['--method', method]
    assert main(args) == 0
    got = json.loads(capsys.readouterr().out)
    if os.environ.get('INERTIA_REGEN_GOLDEN'):   # the log path relative: no checkout's path
        saved = dict(got, diagnostics=dict(got['diagnostics'], log=f'bags/{bag}.mcap'))
        (GOLDEN / name).write_text(json.dumps(saved, indent=2) + '\n')
    want = json.loads((GOLDEN / name).read_text())
    got['diagnostics'].pop('log', None)
    want['diagnostics'].pop('log', None)
    _compare(got, want, name)
