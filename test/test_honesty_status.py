"""Status that means something, sigma true under mismatch (issue 27 items 3 and 4).

Unit checks of the adequacy decision (:mod:`inertia_ros.core.estimation.adequacy`) on
synthetic window estimates with a known scatter, and reduced seeded Monte Carlo on the
independent reference simulator (``bench/truth_sim.py``) through ``estimate()`` with its
defaults; the full figures and commands are in docs/BENCHMARKS.md ("Honesty").
"""
from __future__ import annotations

import numpy as np
import pytest

from inertia_ros.core.estimation.adequacy import (
    MAX_WIDENING,
    check_adequacy,
    segment_shift,
)


def _windows(scale: float, K: int = 4, p: int = 6, seed: int = 0, step: float = 0.0):
    """K window estimates of p parameters whose scatter is ``scale`` x their stated sigma."""
    rng = np.random.default_rng(seed)
    cov = np.eye(p) * 1e-4
    th = 1.0 + rng.normal(0.0, 1e-2 * scale, (K, p))
    th[K // 2:] += step
    return th, np.broadcast_to(cov, (K, p, p)).copy(), np.arange(K) * 10.0 + 5.0


def test_noise_model_scatter_is_ok_and_not_widened() -> None:
    """Windows that scatter as their covariances say: ok, covariance factor 1."""
    a = check_adequacy(*_windows(1.0), excess=1.0)
    assert a.ok and a.benign and a.inflation == 1.0


def test_suspect_scatter_is_ok_with_the_sigma_widened_by_it() -> None:
    """Scatter suspect (p < 0.05) but not failing at 1e-4: ok, sigma widened by 1 + K (B - 1)."""
    a = check_adequacy(*_windows(1.45, seed=4), excess=1.0)
    B = a.chi2 / a.dof
    assert 1e-4 < a.p_value < 1e-2, a
    assert a.ok and a.benign and a.inflation == pytest.approx(1.0 + 4 * (B - 1.0))


def test_small_residual_excess_is_ok_widened() -> None:
    """Residuals 2.5x the noise model, windows consistent: ok (benign), covariance x 2.5."""
    a = check_adequacy(*_windows(1.0), excess=2.5)
    assert not a.ok and a.benign and a.inflation == pytest.approx(2.5)
    assert 'residuals 2.5x' in a.reason


def test_large_scatter_or_a_step_is_a_mismatch() -> None:
    """Scatter 2.5x sigma (fails at 1e-4): more than widening may cover; a step: never benign."""
    a = check_adequacy(*_windows(2.5, K=8, seed=2), excess=1.0)
    assert not a.ok and not a.benign and a.inflation > MAX_WIDENING
    s = check_adequacy(*_windows(1.0, K=8, seed=3, step=0.05), excess=1.0)
    assert not s.benign and s.change_at == pytest.approx(40.0)


def test_segment_shift_calibrated_and_sensitive() -> None:
    """Under the model d ~ N(0, Cs - Cl): chi2 averages its dof; an 8-sigma shift fails."""
    rng = np.random.default_rng(0)
    Cl = np.diag([1.0, 2.0, 0.5, 1.0, 1.0, 3.0]) * 1e-6
    Cs = 3.0 * Cl
    L = np.linalg.cholesky(Cs - Cl)
    stats = [segment_shift(np.zeros(6), Cl, L @ rng.normal(size=6), Cs)[0] for _ in range(400)]
    assert 3.0 < np.mean(stats) < 6.0
    d = np.zeros(6)
    d[2] = 8.0 * np.sqrt(Cl[2, 2])
    Cs = 1.5 * Cl
    chi2, dof, p, max_sigma = segment_shift(np.zeros(6), Cl, d, Cs)
    assert dof == 6 and p < 1e-4 and max_sigma == pytest.approx(8.0)


def test_bias_split_decides_and_widens() -> None:
    """The bias split (a torque bias differing between parts of the record): failing at 1e-4
    by 4.5 per dof is a mismatch naming it; suspect (p 0.01, 2.3 per dof) widens by the four
    pieces' scatter (6.3), ok."""
    from inertia_ros.core.estimation.tails import chi2_sf
    a = check_adequacy(*_windows(1.0, K=0), excess=1.0, split=(40.5, 9, chi2_sf(40.5, 9)))
    assert not a.ok and not a.benign and 'torque bias the fit found differs' in a.reason
    b = check_adequacy(*_windows(1.0, K=0), excess=1.0, split=(21.0, 9, chi2_sf(21.0, 9)))
    # the pieces' scatter over the four pieces, 1 + 4 (21 / 9 - 1): not averaged down
    assert b.ok and b.benign and b.inflation == pytest.approx(1.0 + 4.0 * (21.0 / 9 - 1.0))


def test_few_dof_shift_or_split_beyond_twice_sigma_is_a_mismatch() -> None:
    """A bias split on 3 dof (the node's two groups of a 5 s record) at chi2 14 (p 0.003,
    4.7 per dof: sigma x 2.2) is model_mismatch, not ok widened (before: ok; the node's 5 s
    disturbance record seed 3 so at |z| 6.0); at chi2 8.7 (2.9 per dof) still ok, widened by
    the two groups' scatter.
    The segment shift likewise."""
    from inertia_ros.core.estimation.tails import chi2_sf
    a = check_adequacy(*_windows(1.0, K=0), excess=1.0, split=(14.1, 3, chi2_sf(14.1, 3)))
    assert not a.ok and not a.benign and 'torque bias the fit found differs' in a.reason, a
    b = check_adequacy(*_windows(1.0, K=0), excess=1.0, split=(8.7, 3, chi2_sf(8.7, 3)))
    assert b.ok and b.benign and b.inflation == pytest.approx(1.0 + 2.0 * (2.9 - 1.0))
    s = check_adequacy(*_windows(1.0, K=0), excess=1.0, shift=(26.0, 6, chi2_sf(26.0, 6), 3.0))
    assert not s.ok and 'anchored segments are cut shorter' in s.reason, s


def test_stale_adequacy_verdict_is_not_reused() -> None:
    """The node's schedule (tests every 10 estimates, deferred): a verdict that saw fewer than
    90 % of an estimate's samples is replaced by a test of that estimate's data; a fresher
    one is reused (before: reused for 9 estimates, then reported once more when deferred)."""
    from inertia_ros.core.estimation.schedule import Reselection
    calls = []

    def test(f, nv, tv):
        calls.append(f)
        return f'verdict {f}'
    s = Reselection(10, True)
    z = np.zeros(3)
    for k, n in enumerate((1000, 1050, 1111, 1112, 1200, 1240)):
        s.tick()
        s.window_adequacy(k, z, z, test, n)
    assert calls == [0, 3, 5], calls
    s.tick()
    assert s.window_adequacy(6, z, z, test, 1250) == "verdict 5"


# ---- seeded Monte Carlo on the reference simulator, estimate() with its defaults

def _outcomes(truth, seeds):
    from inertia_ros.bench.honesty import HonestyCase, run_case
    out = run_case('mc', HonestyCase(truth), list(seeds), ('api',))
    z = np.concatenate([o.z[np.isfinite(o.z)] for o in out])
    return out, float(np.sqrt(np.mean(z ** 2)))


_SCENE = dict(amplitude=0.06, torque_noise=0.0012, omega0=(0.05, -0.03, 0.02))


@pytest.mark.parametrize('kind,duration', [('continuous', 10.0), ('zoh', 30.0)])
def test_model_conforming_and_continuous_torque_ok_and_calibrated(kind: str,
                                                                  duration: float) -> None:
    """Continuous torque and held torque: ok in >= 90 %, RMS z in [0.7, 1.5] (8 seeds)."""
    from inertia_ros.bench.truth_sim import TruthCase
    out, rms = _outcomes(TruthCase(torque_kind=kind, duration=duration, **_SCENE), range(8))
    ok = sum(o.status == 'ok' for o in out)
    assert ok >= 7, [o.status for o in out]
    assert 0.7 <= rms <= 1.5, rms


@pytest.mark.parametrize('name,duration', [('gyro_bias', 20.0), ('disturbance', 8.0),
                                           ('payload_change', 20.0)])
def test_faults_never_ok_far_from_the_truth(name: str, duration: float) -> None:
    """Gyro bias, unmodelled torque, payload change: no record ok with some |z| > 5 (8 seeds).

    Before the segment-shift test and the widening, gyro bias at 20 s was ok at |z| 5.4 in
    one of 10 records (seeds 0-9)."""
    from inertia_ros.bench.honesty import CASES
    t = CASES[name].truth.with_(duration=duration)
    if t.t_change is not None:
        t = t.with_(t_change=duration / 2)
    out, _ = _outcomes(t, range(8))
    assert not [o for o in out if o.defect], [(o.status, np.round(o.z, 1)) for o in out]


def test_short_records_conforming_ok_and_slow_disturbance_never_ok_far() -> None:
    """5 s records (no room for time windows): held torque ok in >= 11 of 12 with RMS z in
    [0.7, 1.5]; a 0.01 N m disturbance fixed in space never ok with |z| > 5 (10 seeds).

    Before the bias split and the hold kept by adequacy: conforming 2 of 12 model_mismatch
    (a linear hold chosen on a held torque), the disturbance ok at |z| 12 in seed 3."""
    from inertia_ros.bench.honesty import CASES
    from inertia_ros.bench.truth_sim import TruthCase
    out, rms = _outcomes(TruthCase(duration=5.0, **_SCENE), range(12))
    assert sum(o.status == 'ok' for o in out) >= 11, [o.status for o in out]
    assert 0.7 <= rms <= 1.5, rms
    out, _ = _outcomes(CASES['disturbance'].truth.with_(duration=5.0), range(10))
    assert not [o for o in out if o.defect], [(o.status, np.round(o.z, 1)) for o in out]


def test_short_disturbance_seed_3_is_caught() -> None:
    """The 0.01 N m disturbance (fixed in space) at 5 s, seed 3: not ok with |z| > 5, through
    the Python API and the node's estimator fed as the node feeds it.  Its bias split (29.6 on
    9 dof, p 5e-4) does not fail at 1e-4, and a model-conforming record reaches the same
    statistic; widened by the split's chi2 per dof (sigma x 1.8) both paths were ok at
    |z| 6.5 with izz 4.7 % off.  The pieces' scatter, 1 + 4 (B - 1), covers it (sigma x 3.2)."""
    from inertia_ros.bench.honesty import CASES, HonestyCase, run_case
    out = run_case('seed3', HonestyCase(CASES['disturbance'].truth.with_(duration=5.0)), [3],
                   ('api', 'node'))
    assert len(out) == 2 and not [o for o in out if o.defect], [
        (o.path, o.status, np.round(o.z, 1)) for o in out]


def test_short_disturbance_seed_31_is_caught() -> None:
    """The 0.01 N m disturbance fixed in space at 5 s, seed 31, with the defaults: ``ok`` at
    |z| 6.0 (API, CLI) and 15.6 (node) without the term (``inertial_torque='off'``, the default
    before session 9): the body-fixed bias and the tensor absorbed the torque fixed in space
    and no test saw it.  The default ``'auto'`` screens for the torque fixed in inertial axes
    and fits it: measured ok at |z| 1.8 on every path."""
    from inertia_ros.bench.honesty import CASES, HonestyCase, run_case
    out = run_case('seed31', HonestyCase(CASES['disturbance'].truth.with_(duration=5.0)),
                   [31], ('api', 'cli', 'node'))
    assert len(out) == 3 and not [o for o in out if o.defect], [
        (o.path, o.status, np.round(o.z, 1)) for o in out]
    assert all(o.status != 'ok' or np.nanmax(np.abs(o.z)) <= 4.0 for o in out), [
        (o.path, o.status, np.round(o.z, 1)) for o in out]
    off = run_case('seed31', HonestyCase(CASES['disturbance'].truth.with_(duration=5.0),
                                         node={'inertial_torque': 'off'}), [31], ('node',))
    assert off[0].defect, (off[0].status, np.round(off[0].z, 1))   # (the fault without it)


def test_bias_split_does_not_swing_with_the_noise_level() -> None:
    """The bias split's verdict is a property of the record, not of the third digit of the gyro
    noise level: on the 5 s disturbance record, seed 3, chi2 within 15 % of each other for
    levels 0.99-1.01x the estimated one.  Each piece's noise model was evaluated at the
    piece's own tensor, which a 1.25 s piece barely determines (its bias-compensated
    information is often indefinite): chi2 36, 24, 6, 27, 34, 35 (ok at |z| 6.4-11.9) for
    0.99, 0.994, 0.996, 1.0, 1.004, 1.01 before; at the whole record's tensor now."""
    from inertia_ros.bench.honesty import CASES
    from inertia_ros.bench.truth_sim import simulate_truth
    from inertia_ros.core.estimation import estimate
    from inertia_ros.core.estimation.noise import noise_std_from_differences
    rec = next(iter(simulate_truth(CASES['disturbance'].truth.with_(duration=5.0), [3])))
    g0 = noise_std_from_differences(rec.omega)
    chi2 = [estimate(rec.t_gyro, rec.omega, rec.t_torque, rec.torque, gyro_noise=g0 * s)
            .diagnostics['adequacy']['bias_split_chi2'] for s in (0.99, 0.996, 1.0, 1.01)]
    assert max(chi2) < 1.15 * min(chi2), np.round(chi2, 1)


def test_peer_like_sine_profiles_honest() -> None:
    """Sine on all axes, 0.005 N m, with an unmodelled disturbance of 2e-4 N m (4 % of it)
    and one of 1e-4: never ok with |z| > 5; without it ok with RMS z in [0.7, 1.5]."""
    from inertia_ros.bench.honesty import peer_like
    for level in (2e-4, 1e-4):
        out, _ = _outcomes(peer_like('iso', 0.005, level), range(4))
        assert not [o for o in out if o.defect], (level, [(o.status, o.z) for o in out])
    out, rms = _outcomes(peer_like('iso', 0.005, 0.0), range(4))
    assert all(o.status == 'ok' for o in out) and 0.7 <= rms <= 1.5, (rms, out)


def test_single_axis_sine_windows_hold_the_inertial_torque() -> None:
    """Sine on x only, 0.02 N m, a 2e-4 N m torque fixed in inertial axes (modelled by
    default), 20 s, seeds 0-5: the window test holds the inertial torque at the whole
    record's value.  Fitted per window beside the two moments only the gyroscopic coupling
    excites, it made the windows disagree far beyond their sigmas: 10 of 20
    ``model_mismatch`` at |z| < 1; now ok in at least 5 of 6, RMS z in [0.6, 1.5], never ok
    beyond 5 sigma."""
    from inertia_ros.bench.honesty import peer_like
    out, rms = _outcomes(peer_like('x', 0.02, 2e-4, 20.0), range(6))
    assert sum(o.status == 'ok' for o in out) >= 5, [(o.status, o.z) for o in out]
    assert not [o for o in out if o.defect] and 0.6 <= rms <= 1.5, rms


@pytest.mark.parametrize('axes, amplitude, duration, seed', [
    ('x', 0.005, 10.0, 12), ('x', 0.005, 5.0, 1), ('x', 0.005, 5.0, 11), ('z', 0.005, 5.0, 11)])
def test_a_degenerate_fit_is_not_ok_by_its_own_noise_model(axes: str, amplitude: float,
                                                           duration: float, seed: int) -> None:
    """Peer-like sines on one axis, short records: fits whose residuals are 0.11-0.38 of
    what the noise model predicts (the fit absorbs the noise: a bias and an inertial torque
    beside two weakly excited moments, or the moments alone) were ok at |z| 45, 47, 17 and
    7.4 (the first gave moments 0.004, 0.94, 0.98 with sigma 0.017 on ``iyy``).  A residual
    excess below ``MIN_RESIDUAL_EXCESS`` is not ok: never ok beyond 5 sigma.  (The noise
    model taken at the fit without the disturbances fixed the first and made three 5 s
    records of a sine on y ok at |z| 11-15: not done.)"""
    from inertia_ros.bench.honesty import peer_like
    out, _ = _outcomes(peer_like(axes, amplitude, 2e-4, duration), [seed])
    assert not out[0].defect, (out[0].status, out[0].z)


def test_covered_mismatch_says_by_how_much_and_why() -> None:
    """A small unmodelled torque the windows see at p ~ 3e-4: ok, sigma widened (> 1.5x), the
    widening and its cause in the diagnostics and a warning; the truth within 3 sigma.  (The
    torque is fixed in inertial axes, which the default ``inertial_torque='auto'`` models:
    unmodelled here with ``'off'``; the default fits it and needs no widening.)"""
    from inertia_ros.bench.honesty import peer_like
    from inertia_ros.bench.truth_sim import simulate_truth
    from inertia_ros.core.estimation import estimate
    from inertia_ros.core.inertia import matrix_to_theta
    rec = simulate_truth(peer_like('iso', 0.005, 1e-4), [0])[0]
    default = estimate(rec.t_gyro, rec.omega, rec.t_torque, rec.torque)
    z = (default.theta - matrix_to_theta(rec.inertia_end)) / default.theta_std
    assert default.status == 'ok' and default.model.endswith('+inertial'), default.model
    assert default.diagnostics['adequacy']['sigma_widened_by'] < 1.2 and np.max(np.abs(z)) < 3
    e = estimate(rec.t_gyro, rec.omega, rec.t_torque, rec.torque, inertial_torque='off')
    a = e.diagnostics['adequacy']
    assert e.status == 'ok' and a['sigma_widened_by'] > 1.5, a
    assert a['covariance'].startswith('noise model x window scatter')
    assert any(f"sigma widened {a['sigma_widened_by']:.3g}x" in w
               for w in e.diagnostics['warnings']), e.diagnostics['warnings']
    z = (e.theta - matrix_to_theta(rec.inertia_end)) / e.theta_std
    assert np.max(np.abs(z)) < 3.0, z


def test_node_path_segment_shift_and_bias_split() -> None:
    """Through the node's estimator (10 Hz estimates, adequacy deferred): conforming 5 s and
    10 s records all ok (8 seeds each); a 0.01 N m disturbance fixed in space at 10 s never
    ok with |z| > 5 (10 seeds; before the online segment shift and bias split: ok 2, one at
    |z| 15.8) and at 5 s at most 2 of 10 (measured 1; before: 8, up to 15.7)."""
    from inertia_ros.bench.honesty import CASES, HonestyCase, run_case
    from inertia_ros.bench.truth_sim import TruthCase
    for dur in (5.0, 10.0):
        out = run_case('c', HonestyCase(TruthCase(duration=dur, **_SCENE)), range(8), ('node',))
        assert all(o.status == 'ok' for o in out), (dur, [o.status for o in out])
    for dur, most in ((10.0, 0), (5.0, 2)):
        out = run_case('d', HonestyCase(CASES['disturbance'].truth.with_(duration=dur)),
                       range(10), ('node',))
        assert sum(o.defect for o in out) <= most, (dur, [(o.status, o.z) for o in out])


def test_torque_free_status_by_the_same_rule() -> None:
    """Torque-free 20 s tumbles of the reference simulator (3, 4, 5 rad/s, 0.01 rad/s gyro
    noise): 10 seeds all scale_unobservable (no false alarm); with a 0.01 rad/s gyro bias
    model_mismatch in each of 4 (the segment shift sees it; before, all 4 stayed
    scale_unobservable with |z| 8-10: the 5 s windows did not see it)."""
    from inertia_ros.bench.truth_sim import TruthCase, simulate_truth
    from inertia_ros.core.estimation import estimate
    case = TruthCase(inertia=np.diag([2.0e-3, 1.5e-3, 3.0e-3]), omega0=(3.0, 4.0, 5.0),
                     duration=20.0, gyro_rate=100, torque_rate=100, gyro_noise=0.01,
                     torque_noise=0.0, amplitude=0.0)
    recs = simulate_truth(case, range(10))

    def status(r, bias):
        return estimate(r.t_gyro, r.omega + np.array([bias, 0.0, 0.0]), np.zeros(0),
                        np.zeros((0, 3)), method='integral').status
    assert [status(r, 0.0) for r in recs] == ['scale_unobservable'] * 10
    assert [status(r, 0.01) for r in recs[:4]] == ['model_mismatch'] * 4


def test_node_hold_auto_keeps_the_hold_whose_fit_passes() -> None:
    """Node path, ``hold: auto`` (its default), continuous torque 10 s: ok in 6 of 6 with RMS
    z in [0.7, 1.5] (before: seed 2 model_mismatch at |z| 0.5, the Vuong test undecided on 9
    windows, so zoh, whose fit the segment shift rightly failed); the choice says the adequacy
    tests made it.  The same torque with a 0.01 N m disturbance is never ok with |z| > 5
    (3 seeds; 10 measured: all model_mismatch)."""
    from inertia_ros.bench.honesty import _node, _z
    from inertia_ros.bench.truth_sim import TruthCase, simulate_truth
    cont = TruthCase(torque_kind='continuous', duration=10.0, **_SCENE)
    dist = cont.with_(disturbance=(0.01, 0.01, -0.01), disturbance_kind='inertial')
    zs = []
    for rec in simulate_truth(cont, list(range(6))):
        status, inertia, std = _node(rec, {'hold': 'auto'})
        assert status == 'ok', (rec.seed, status)
        zs.append(_z(inertia, std, rec.inertia_end)[0])
    assert 0.7 <= float(np.sqrt(np.nanmean(np.concatenate(zs) ** 2))) <= 1.5
    for rec in simulate_truth(dist, [0, 1, 2]):
        status, inertia, std = _node(rec, {'hold': 'auto'})
        z = _z(inertia, std, rec.inertia_end)[0]
        assert status != 'ok' or np.nanmax(np.abs(z)) <= 5.0, (rec.seed, status, z)


def test_node_hold_of_seed_2_by_the_likelihoods() -> None:
    """Seed 2 above: the Vuong test could not tell, the adequacy tests chose linear; the
    likelihoods now do (linear's residual excess 4.6 % below the held one's)."""
    from inertia_ros.bench.honesty import feed_online
    from inertia_ros.bench.truth_sim import TruthCase, simulate_truth
    from inertia_ros.core.estimation import RecursiveEstimator
    rec = simulate_truth(TruthCase(torque_kind='continuous', duration=10.0, **_SCENE), [2])[0]
    e = feed_online(RecursiveEstimator(model='full', torque_bias='auto', hold='auto',
                                       reselect_every=10, defer_adequacy=True), rec)
    sel = e.diagnostics['hold_selection']
    assert e.status == 'ok' and sel['chosen'] == 'linear' and sel['statistic'] < -0.01, sel
    assert 'adequacy' not in sel, sel


def test_tracker_after_an_untested_change_is_not_ok_far() -> None:
    """The node's tracker (its defaults, fed in 0.1 s blocks) on the 5 s disturbance records
    10 and 13: each detected a "change" late, too late for any innovation test, and the
    recent change excused an innovation excess of 5.3 and 2.9: ok at |z| 8.4 (izz 87 % off)
    and 10.1.  Where no test vouches, the excess decides: not ok with |z| > 5."""
    from inertia_ros.bench.honesty import CASES, feed_online
    from inertia_ros.bench.truth_sim import simulate_truth
    from inertia_ros.core.estimation.tracking import TrackingEstimator
    iu = np.triu_indices(3)
    for rec in simulate_truth(CASES['disturbance'].truth.with_(duration=5.0), [10, 13]):
        e = feed_online(TrackingEstimator(window=10.0, model='full', torque_bias='auto',
                                          hold='auto'), rec, 10.0)
        if e.status != 'ok':
            continue
        z = ((e.inertia - rec.inertia) / e.inertia_std)[iu]
        assert np.nanmax(np.abs(z)) <= 5.0, (e.status, np.round(z, 1))


def test_bias_dropped_on_a_suspect_test_keeps_its_covariance() -> None:
    """A 0.01 rad/s gyro bias on a 5 s record acts like a torque bias: on seed 26 the bias
    test gave p 0.006, not significant at 1e-3, so the bias was dropped and the result was
    ok at |z| 5.7 with the covariance of the fit without it.  Dropped on such weak evidence
    the tensor keeps the bias fit's covariance (``selection.dropped_bias_cov``): not ok with
    |z| > 5 through the API and the node."""
    from inertia_ros.bench.honesty import CASES, HonestyCase, run_case
    out = run_case('seed26', HonestyCase(CASES['gyro_bias'].truth.with_(duration=5.0)), [26],
                   ('api', 'node'))
    assert len(out) == 2 and not [o for o in out if o.defect], [
        (o.path, o.status, np.round(o.z, 1)) for o in out]


def test_dropped_bias_covariance_is_the_weighted_positive_difference() -> None:
    """``dropped_bias_cov``: ``weight [C_B - C_0]_+`` (never negative, 0 at weight 0)."""
    from types import SimpleNamespace

    from inertia_ros.core.estimation.selection import dropped_bias_cov
    C0 = np.diag([1.0, 2.0, 1.0, 1.0, 1.0, 1.0]) * 1e-6
    CB = np.zeros((9, 9))
    CB[:6, :6] = np.diag([3.0, 1.0, 1.0, 1.0, 1.0, 2.0]) * 1e-6     # smaller on iyy
    a = dropped_bias_cov(SimpleNamespace(cov=C0), SimpleNamespace(cov=CB), 0.5)
    assert np.allclose(a, 0.5 * np.diag([2.0, 0.0, 0.0, 0.0, 0.0, 1.0]) * 1e-6, atol=1e-15)
    assert np.all(np.linalg.eigvalsh(a) >= -1e-18)
    assert np.allclose(dropped_bias_cov(SimpleNamespace(cov=C0), SimpleNamespace(cov=CB), 0.0),
                       0.0)


def test_bias_split_scatter_counts_pieces_not_parameters() -> None:
    """With the torque fixed in inertial axes the split tests 6 parameters per piece: 4
    pieces give 18 dof, and the scatter is 1 + 4 (B - 1), not 1 + 7 (B - 1) (the pieces
    read back from the dof as if the disturbance had 3 parameters)."""
    from inertia_ros.core.estimation.tails import chi2_sf
    a = check_adequacy(*_windows(1.0, K=0), excess=1.0,
                       split=(30.0, 18, chi2_sf(30.0, 18), 4))
    assert a.ok and a.split_pieces == 4
    assert a.inflation == pytest.approx(1.0 + 4.0 * (30.0 / 18 - 1.0))
