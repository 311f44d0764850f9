"""False alarms on short model-conforming records (issue 27, session 5).

A status that cries wolf on a correct answer is as useless as one that stays green on a
wrong one.  Two found by the capability matrix's combined-feature cells:

- ``nuisance='auto'`` on a few seconds of slow rotation: the interval equations' rate
  changes were mostly gyro noise, the fit shrunk the tensor (errors in variables) and the
  selection test chose gyro biases of 0.3-2 rad/s at p < 1e-10, then ``model_mismatch``
  (20 of 20 records at 6 s, median error 46 %).  Now the fit is corrected for the noise in
  its regressors and refused when the equations with every candidate do not determine the
  tensor (the batch identifiability rule): :mod:`inertia_ros.core.estimation.nuisance`.
- The tracker (the node's ``method: tracking``) on 4 s: its start-up fit had the same
  shrink with a covariance that claimed 1 %, so the filter stayed many sigma off for
  seconds (``ok`` at |z| up to 15, or ``model_mismatch``); and before the hold is locked it
  reported the linear hold's filter on a held torque, preferred by a coin toss, whose
  innovations then failed.  :mod:`inertia_ros.core.estimation.tracking`.

Records from the independent reference simulator (``bench/truth_sim.py``), the scene of
``scripts/measure/honest_status.py`` (0.06 N m held torque, 0.05 rad/s start); the full
Monte Carlo and the commands are in docs/BENCHMARKS.md ("Status and sigma under mismatch").
"""
from __future__ import annotations

import numpy as np
import pytest

from inertia_ros.bench.honesty import feed_online
from inertia_ros.bench.truth_sim import TruthCase, simulate_truth
from inertia_ros.core.estimation import estimate
from inertia_ros.core.estimation.tracking import TrackingEstimator

IDX = ([0, 1, 2, 0, 0, 1], [0, 1, 2, 1, 2, 2])
SCENE = TruthCase(amplitude=0.06, torque_noise=0.0012, omega0=(0.05, -0.03, 0.02))
#: the node's tracker at its defaults (memory 10 s, torque bias and hold 'auto')
NODE_TRACKER = {'window': 10.0, 'model': 'full', 'torque_bias': 'auto', 'hold': 'auto'}


def _z(e, rec) -> np.ndarray:
    return (e.theta - rec.inertia_end[IDX]) / e.theta_std


def _summary(pairs) -> tuple[list[str], float, float]:
    """Statuses, RMS z over the ok records and their largest |z|."""
    ok = [_z(e, r) for e, r in pairs if e.status == 'ok']
    z = np.concatenate(ok) if ok else np.zeros(1)
    return [e.status for e, _ in pairs], float(np.sqrt(np.mean(z ** 2))), float(np.max(np.abs(z)))


@pytest.mark.slow
def test_nuisance_auto_does_not_cry_wolf_on_short_conforming_records() -> None:
    """8 model-conforming 6 s records, ``nuisance='auto'``: at most 1 not ok (was 8 of 8
    ``model_mismatch`` with gyro biases of 0.3-2 rad/s), RMS z of the ok ones in
    [0.7, 1.5], none over 5; where the fit is refused, the record says why in one line."""
    recs = simulate_truth(SCENE.with_(duration=6.0), list(range(8)))
    pairs = [(estimate(r.t_gyro, r.omega, r.t_torque, r.torque, nuisance='auto'), r)
             for r in recs]
    statuses, rms, top = _summary(pairs)
    assert statuses.count('ok') >= 7, statuses
    assert 0.7 <= rms <= 1.5 and top < 5.0, (rms, top)
    for e, _ in pairs:
        nd = e.diagnostics['nuisance']
        assert nd['chosen'] == [] or max(np.abs(nd['values'].get('gyro_bias', [0.0]))) < 0.05
        why = nd.get('skipped', '')
        assert '\n' not in why and (not why or 'tensor' in why or 'noise' in why), why


def test_nuisance_fit_is_not_shrunk_by_the_gyro_noise() -> None:
    """On 10 s records whose 0.1 s intervals' rate changes carry 6-9 % gyro-noise power, the
    nuisance fit's tensor (no term chosen: the fit of the tensor and the disturbance) is
    the truth within 4 % in the mean of the principal moments over 4 seeds (without the
    correction for the noise in the regressors it is shrunk by about the noise share)."""
    from inertia_ros.core.estimation.nuisance import fit_nuisance

    ratios = []
    for r in simulate_truth(SCENE.with_(duration=10.0), list(range(4))):
        fit, record = fit_nuisance(r.t_gyro, r.omega, r.t_torque, r.torque, 'auto', 1e-3)
        assert fit is not None and record['chosen'] == [], record
        ratios.append(np.mean(fit.beta[:3] / np.diag(r.inertia_end)))
    assert abs(np.mean(ratios) - 1.0) < 0.04, ratios


@pytest.mark.slow
def test_tracker_is_calibrated_on_short_conforming_records() -> None:
    """The node's tracker fed 8 model-conforming 4 s records at 10 Hz: at most 1 not ok,
    RMS z of the ok ones in [0.7, 1.5], none ok with |z| > 5 (before: 2 of the 8
    ``model_mismatch`` and 2 ok at |z| 9.8 and 15)."""
    recs = simulate_truth(SCENE.with_(duration=4.0), list(range(8)))
    pairs = [(feed_online(TrackingEstimator(**NODE_TRACKER), r, 10.0), r) for r in recs]
    statuses, rms, top = _summary(pairs)
    assert statuses.count('ok') >= 7, statuses
    assert 0.7 <= rms <= 1.5 and top < 5.0, (rms, top)


def test_tracker_start_up_is_not_shrunk() -> None:
    """The first estimate after the start-up (2 s of slow rotation, the seed whose moment
    iyy the uncorrected fit shrank from 1.2 to 0.19 kg m^2 at a claimed sigma of 0.5 %)
    is within 5 sigma of the truth, or the start-up waits for more data."""
    rec = simulate_truth(SCENE.with_(duration=3.0), [2])[0]
    first = []
    feed_online(TrackingEstimator(window=10.0, hold='zoh'), rec, 10.0,
                lambda t, e: first.append(e) if e.status != 'insufficient_data' else None)
    assert first, 'never started'
    z = _z(first[0], rec)
    assert np.all(np.abs(z) < 5.0), np.round(z, 1)


def test_tracker_hold_kept_by_adequacy_before_it_is_locked(monkeypatch) -> None:
    """Seed 11 at 4 s, the rule made to prefer the linear hold on the held torque (the Vuong
    rule did so, not significant; the likelihood rule picks zoh): its filter fails the
    innovation test, the zero-order hold's passes and is reported, not locked,
    ``hold_selection.adequacy`` saying so (before: model_mismatch)."""
    from inertia_ros.core.estimation import online_hold
    monkeypatch.setattr(online_hold, 'select_hold', lambda ez, el: (
        'linear', {'test': 'likelihood', 'statistic': -0.001, 'chosen': 'linear'}))
    rec = simulate_truth(SCENE.with_(duration=4.0), [11])[0]
    e = feed_online(TrackingEstimator(**NODE_TRACKER), rec, 10.0)
    sel = e.diagnostics['hold_selection']
    assert e.status == 'ok' and sel['chosen'] == 'zoh' and not sel['locked'], sel
    assert sel['adequacy']['preferred'] == 'linear', sel
    assert sel['adequacy']['innovation_excess']['linear'] > 1.5, sel


def _fault(name: str, duration: float, seed: int):
    """The honesty benchmark's fault ``name`` (a change at half the record), the node's
    tracker at its defaults, its last estimate and the record."""
    from inertia_ros.bench.honesty import CASES
    truth = CASES[name].truth.with_(duration=duration)
    if truth.t_change is not None:
        truth = truth.with_(t_change=duration / 2)
    rec = simulate_truth(truth, [seed])[0]
    return feed_online(TrackingEstimator(**NODE_TRACKER), rec, 10.0), rec


_SLOW = pytest.mark.slow


@pytest.mark.parametrize('name, duration, seed', [
    pytest.param('gyro_bias', 20.0, 0),
    pytest.param('gyro_bias', 20.0, 1, marks=_SLOW),
    pytest.param('disturbance', 20.0, 9, marks=_SLOW)])
def test_tracker_flags_a_fault_it_half_absorbs(name: str, duration: float, seed: int) -> None:
    """A 0.01 rad/s gyro bias or a 0.01 N m unmodelled torque, records the innovation excess
    passed (before: ok at |z| 7.1, 5.2 and 11.2): ``model_mismatch``, the innovation
    consistency test named in ``diagnostics['adequacy']`` with the test that failed (the
    average NIS, the mean or the fault score; the whiteness test is reported, it does not
    decide).  Gyro bias seed 0 passed the average NIS (p 3.3e-3, NIS/dof 1.13, inside the
    0.92-1.14 of model-conforming 20 s records) and the mean (p 0.21) once the gyro noise
    level was estimated unbiased; the fault score rejects it (p 1.2e-6)."""
    e, rec = _fault(name, duration, seed)
    assert e.status == 'model_mismatch', (e.status, np.round(_z(e, rec), 1))
    if 'adequacy' not in e.diagnostics:        # the persistent innovation excess fired first
        assert 'times the noise model' in e.diagnostics['reason'], e.diagnostics['reason']
        return
    a = e.diagnostics['adequacy']
    assert not a['ok'] and a['test'].startswith('innovation consistency'), a
    assert min(a.get(f'{k}_p_value', 1.0) for k in ('anis', 'mean', 'fault')) < a['level'], a
    if 'times the noise model' not in e.diagnostics['reason']:     # the excess fired first
        assert 'innovations fail' in e.diagnostics['reason'], e.diagnostics['reason']


@pytest.mark.parametrize('name, seed', [('gyro_bias', 6), ('disturbance', 7)])
def test_tracker_fault_score_catches_what_the_segment_tests_miss(name: str, seed: int) -> None:
    """10 s records the consistency tests of session 6 passed, ``ok`` at |z| 6.1 (a 0.01
    rad/s gyro bias: average NIS p 0.012, mean p 0.0010) and 7.4 (a 0.01 N m disturbance
    fixed in inertial axes: two changes detected, the segment since too short to test):
    ``model_mismatch`` by the fault score test (the gyro bias's and a constant torque's
    signature through the filter's gains, chi2 with 6 dof, spanning the detected changes),
    p < 1e-5 (the reason names it, or the persistent innovation excess that fired first)."""
    e, rec = _fault(name, 10.0, seed)
    a = e.diagnostics['adequacy']
    assert e.status == 'model_mismatch' and not a['ok'], (e.status, np.round(_z(e, rec), 1))
    assert a['fault_p_value'] < 1e-5 and a['fault_dof'] == 6, a
    reason = e.diagnostics['reason']        # or the persistent innovation excess first
    assert 'fault' in reason or 'times the noise model' in reason, reason


@pytest.mark.slow
@pytest.mark.parametrize('seed', [0, 1])
def test_tracker_followed_payload_change_is_no_fault(seed: int) -> None:
    """A 20 % payload change at 10 s of 20 that the tracker detects and follows: ``ok``,
    within 5 sigma of the final truth, the consistency test passing on the blocks since."""
    e, rec = _fault('payload_change', 20.0, seed)
    assert e.status == 'ok' and np.all(np.abs(_z(e, rec)) < 5.0), (e.status, _z(e, rec))
    assert e.diagnostics['adequacy']['ok'], e.diagnostics['adequacy']
    assert e.diagnostics['adequacy']['since_s'] > 10.0, e.diagnostics['adequacy']


def test_tracker_widens_by_a_suspect_fault_score() -> None:
    """A 0.01 rad/s gyro bias over 5 s, seed 8: 18 blocks, fault score p 0.035, no test
    fails at the level; it was ``ok`` at |z| 5.05 on the noise model's sigma.  Tests that
    pass but are suspect widen the tracker's sigma as they do the batch's (in full below
    p 0.05, in part up to 0.1, by the largest chi2 per dof): ok, covered within 4 sigma."""
    e, rec = _fault('gyro_bias', 5.0, 8)
    a = e.diagnostics['adequacy']
    assert a['ok'] and 1e-3 < a['fault_p_value'] < 0.05, a
    assert a['sigma_widened_by'] > 1.2, a
    assert e.status == 'ok' and np.all(np.abs(_z(e, rec)) < 4.0), (e.status, _z(e, rec))
