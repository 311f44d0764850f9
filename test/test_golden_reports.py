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
#: Relative tolerance of a number: reordered floating-point sums, nothing more.  Another
#: CPU's BLAS kernels (or thread count) sum in another order, and the ill-conditioned steps
#: (the filtered method's filter, Newey-West sums, a converged Gauss-Newton step of 1e-3
#: sigma) amplify that rounding to ~1e-8 relative; 1e-6 is still a thousand times below the
#: smallest standard error of any saved estimate (~1e-3 relative), so a real change fails.
RTOL = 1e-6


def _numbers(x: object) -> list[float]:
    """Every float in a (nested) list."""
    if isinstance(x, list):
        return [v for item in x for v in _numbers(item)]
    return [float(x)] if isinstance(x, float) else []


def _compare(got: object, want: object, where: str, scale: float = 0.0) -> None:
    """``got == want`` with numbers to :data:`RTOL` of themselves or of their array's largest
    element (``scale``: a covariance's near-zero off-diagonal rounds like its diagonal)."""
    if isinstance(want, dict):
        assert isinstance(got, dict) and set(got) == set(want), (
            f'{where}: keys differ: {sorted(set(got) ^ set(want))}')
        for k in want:
            _compare(got[k], want[k], f'{where}.{k}')
    elif isinstance(want, list):
        assert isinstance(got, list) and len(got) == len(want), f'{where}: length differs'
        nums = _numbers(want)
        scale = scale or max((abs(v) for v in nums if np.isfinite(v)), default=0.0)
        for i, (g, w) in enumerate(zip(got, want, strict=True)):
            _compare(g, w, f'{where}[{i}]', scale)
    elif isinstance(want, float) and not isinstance(want, bool):
        assert isinstance(got, (int, float)), f'{where}: {got!r} is not a number'
        assert np.isclose(got, want, rtol=RTOL, atol=max(RTOL * scale, 1e-15)), (
            f'{where}: {got!r} != {want!r}')
    else:
        assert got == want, f'{where}: {got!r} != {want!r}'


def test_compare_catches_a_real_change() -> None:
    """The tolerance passes rounding and fails a change a user could see (1e-4 relative)."""
    want = {'inertia': [[0.1, 1e-9], [1e-9, 0.2]], 'excess': 1.0}
    _compare({'inertia': [[0.1 * (1 + 1e-8), 1.05e-9], [1e-9, 0.2]], 'excess': 1.0 + 1e-9},
             want, 'rounding')
    for bad in ({'inertia': [[0.1 * (1 + 1e-4), 1e-9], [1e-9, 0.2]], 'excess': 1.0},
                {'inertia': [[0.1, 1e-9], [1e-9, 0.2]], 'excess': 1.0001}):
        with pytest.raises(AssertionError):
            _compare(bad, want, 'change')


@pytest.mark.parametrize('method', METHODS)
@pytest.mark.parametrize('bag', BAGS)
def test_report_unchanged(bag: str, method: str, tmp_path: Path,
                          capsys: pytest.CaptureFixture) -> None:
    """The JSON report of a committed bag equals the saved one (numbers to :data:`RTOL`)."""
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
