"""Acceptance on the TU Delft thrown-flywheel recordings (issues 14, 27), when the user has them.

The data set states no licence, so nothing of it is shipped: set ``INERTIA_ROS_TUDELFT_INDEX``
to the ``index.json`` of the converted throws (``scripts/tudelft_throw.py``; the CSVs next to
it) to run the real-data tests; without it only the data-free checks run.
"""
from __future__ import annotations

import importlib.util
import json
import os
from pathlib import Path

import numpy as np
import pytest

from conftest import ROOT

SCRIPT = ROOT / 'scripts' / 'tudelft_throw.py'
REAL = Path(os.environ.get('INERTIA_ROS_TUDELFT_INDEX', '/nonexistent/index.json'))
#: The authors' own pipeline on the same 45 throws (``make table`` at f83da37, rerun):
#: median of eps, the orientation-free error of the sorted principal moments.
AUTHORS_MEDIAN_EPS = 0.0144


def _load():
    spec = importlib.util.spec_from_file_location('tudelft_throw', SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    assert spec.loader is not None
    spec.loader.exec_module(mod)
    return mod


def test_proof_body_is_the_authors_cuboid():
    """The calibration cuboid as in the authors' config.py (not the sorted diagonal)."""
    m, I = _load().proof_body({'proof_body': {'m': 0.346, 'dims': [0.0302, 0.06, 0.07]}})
    assert m == 0.346
    assert np.allclose(np.diag(I), [1.6758e-4, 1.3010e-4, 2.4508e-4], rtol=1e-4)


def test_throw_start_is_the_authors_rule():
    """The throw starts at the sample before the flywheel first exceeds 10 rad/s."""
    mod = _load()
    assert mod.throw_start(np.array([0.0, 3.0, 9.9, 10.5, 40.0])) == 2
    assert mod.throw_start(np.array([0.0, -11.0])) == 0
    assert mod.throw_start(np.zeros(5)) is None


def test_bfl_without_orangebox_says_what_to_install(tmp_path: Path,
                                                     monkeypatch: pytest.MonkeyPatch):
    """A .BFL log without the optional decoder: one line naming the package, no traceback."""
    import sys

    monkeypatch.setitem(sys.modules, 'orangebox', None)
    p = tmp_path / 'LOG00001.BFL'
    p.write_bytes(b'H Product:Blackbox flight data recorder\n')
    with pytest.raises(SystemExit, match=r'pip install orangebox==0\.5\.0'):
        _load().read_throw_csv(p)


def test_reference_fit_recovers_a_noise_free_throw():
    """The authors' estimator re-stated (20 Hz filter, differences, OLS) gives back a
    simulated whole-body tensor ``I - J 1`` within 1 % on a noise-free throw."""
    from flywheel_throw import J, flywheel_throw

    r = flywheel_throw(1.0, 300.0)
    s = {'t': r.t_gyro, 'w': r.omega, 'a': np.zeros_like(r.omega),
         'wheel': r.wheel_speed[:, 0]}
    Ip, _ = _load().reference_fit(s, (300, len(r.t_gyro) - 300), J)
    want = np.asarray(r.inertia) - J * np.eye(3)
    assert np.linalg.norm(Ip - want) / np.linalg.norm(want) < 0.01


def test_summary_counts_ok_above_ten_percent(capsys: pytest.CaptureFixture):
    """The bench summary names the acceptance figures, per configuration and overall."""
    rows = [{'config': 'c', 'status': 'ok', 'eps': 0.12, 'fro': 0.1, 'psi_deg': 1.0,
             'z': [0.5, 1.0, 4.0]},
            {'config': 'c', 'status': 'model_mismatch', 'eps': 0.01, 'fro': 0.02,
             'psi_deg': 2.0, 'z': [0.1, 0.2, 0.3]}]
    _load().summary(rows)
    out = capsys.readouterr().out
    assert 'eps median 6.50 %' in out and 'within 3 sigma 83%' in out
    assert 'ok with eps > 10 %: 1' in out


@pytest.mark.skipif(not REAL.is_file(), reason='TU Delft recordings absent (not shipped: no '
                    'licence; set INERTIA_ROS_TUDELFT_INDEX); see docs/real_data_tudelft.md')
@pytest.mark.parametrize('calibration', ['authors', 'ours'])
def test_real_throws_acceptance(tmp_path: Path, calibration: str) -> None:
    """Filtered form, cutoff below the flywheel's rotation: no ok with eps > 10 % and >= 90 %
    of the principal moments within 3 sigma (both calibrations); the median eps at or below
    the authors' with their calibration (measured 1.35 % vs 1.44 %; ours: 1.49 %)."""
    res = tmp_path / 'r.json'
    assert _load().main(['bench', '--csv-root', str(REAL.parent), '--index', str(REAL),
                         '--calibration', calibration, '--out', str(res)]) == 0
    rows = [r for r in json.loads(res.read_text()) if 'eps' in r]
    assert len(rows) >= 40
    assert not [r['log'] for r in rows if r['status'] == 'ok' and r['eps'] > 0.10]
    z = np.concatenate([r['z'] for r in rows])
    assert np.mean(np.abs(z) <= 3) >= 0.90
    median = float(np.median([r['eps'] for r in rows]))
    assert median <= (AUTHORS_MEDIAN_EPS if calibration == 'authors' else 0.016)


@pytest.mark.skipif(not REAL.is_file(), reason='TU Delft recordings absent (not shipped: no '
                    'licence; set INERTIA_ROS_TUDELFT_INDEX); see docs/real_data_tudelft.md')
def test_real_throws_cli_defaults(tmp_path: Path) -> None:
    """Issue 27: every throw's window through the plain CLI, defaults only (``estimate W.mcap
    --wheels flywheel.yaml``): >= 90 % of the principal moments within 3 sigma (98 %), no ok
    with eps > 10 % (max 4.2 %), the filtered form chosen on every throw, and the whole-body
    tensor's diagonal scatter / reported sigma within [0.5, 2] in every configuration
    (0.56-1.56 with the Newey-West small-sample correction; 0.88-2.38 without), and the
    median eps at or below the authors' (1.39 % vs 1.44 %, since the parameter set is chosen
    by the MSE criterion: B/LOG00160's products, Wald 12.9 on 3 dof, no longer held at zero;
    1.49 % with the Wald test of a zero at 1e-3), the full model on every throw.

    Not met, so not asserted as such: the products' scatter / sigma within [0.5, 2] (6 of 12
    outside, up to 3.3; docs/real_data_tudelft.md), in part a gyro axis coupling of 0.3-0.6 %
    common to the throws."""
    res = tmp_path / 'r.json'
    assert _load().main(['bench', '--csv-root', str(REAL.parent), '--index', str(REAL),
                         '--cli', '--out', str(res)]) == 0
    rows = [r for r in json.loads(res.read_text()) if 'eps' in r]
    assert len(rows) >= 40
    assert {r['method'] for r in rows} == {'filtered'}
    assert not [r['log'] for r in rows if r['status'] == 'ok' and r['eps'] > 0.10]
    z = np.concatenate([r['z'] for r in rows])
    assert np.mean(np.abs(z) <= 3) >= 0.90
    assert float(np.median([r['eps'] for r in rows])) <= AUTHORS_MEDIAN_EPS
    assert {r['model'].removesuffix('+bias') for r in rows} == {'full'}
    for config in {r['config'] for r in rows}:
        q = _load().scatter_ratio([r for r in rows if r['config'] == config])[:3]
        assert np.all((q >= 0.5) & (q <= 2.0)), (config, q)


@pytest.mark.skipif(not REAL.is_file(), reason='TU Delft recordings absent (not shipped: no '
                    'licence; set INERTIA_ROS_TUDELFT_INDEX); see docs/real_data_tudelft.md')
def test_reference_reproduces_the_authors_median(tmp_path: Path) -> None:
    """The authors' pipeline re-stated here, on the index's BFL-decoded throws and
    calibration, gives their median eps (1.44 %, ``make table`` at f83da37)."""
    res = tmp_path / 'r.json'
    assert _load().main(['bench', '--csv-root', str(REAL.parent), '--index', str(REAL),
                         '--method', 'reference', '--out', str(res)]) == 0
    rows = [r for r in json.loads(res.read_text()) if 'eps' in r]
    assert float(np.median([r['eps'] for r in rows])) == pytest.approx(AUTHORS_MEDIAN_EPS,
                                                                      abs=5e-4)
