"""The Kalman tracker (core/estimation/tracking.py) against a forgetting RLS of the same memory.

Seeded Monte Carlo at reduced size on the independent reference simulator (bench/truth_sim.py):
20 records of 36 s per scene (the benchmark runs 120 s), memory 10 s for both estimators.
Acceptance of issue 15 item 5: on a +20 % payload step and on a 1 %/min drift the tracker's
RMS error against the current tensor is at or below the baseline's, and on the drift its sigma
is calibrated against the current tensor (RMS z of the six elements in [0.7, 1.5]).
"""
from __future__ import annotations

import time

import numpy as np
import pytest

from inertia_ros.bench.tracking import run_scene
from inertia_ros.bench.truth_sim import TruthCase, simulate_truth
from inertia_ros.core.estimation.tracking import TrackingEstimator

SEEDS = range(20)
STEP = TruthCase(duration=36.0, t_change=18.0, change=0.20)
DRIFT = TruthCase(duration=36.0, drift_per_s=-0.01 / 60.0)


@pytest.fixture(scope='module')
def step():
    return run_scene('step', SEEDS, 10.0, case=STEP)


@pytest.fixture(scope='module')
def drift():
    return run_scene('drift', SEEDS, 10.0, case=DRIFT)


def test_step_error_at_or_below_rls(step) -> None:
    """Payload +20 %: per record and in the median, the tracker's error <= the RLS's."""
    tr, rl = np.array(step.tracker), np.array(step.rls)
    assert np.all(tr <= rl), (tr, rl)
    assert np.median(tr) <= 0.5 * np.median(rl)


def test_step_is_detected_once(step) -> None:
    """The innovation test finds the step (at least once in every record, rarely more)."""
    assert min(step.changes) >= 1
    assert np.median(step.changes) == 1


def test_drift_error_at_or_below_rls(drift) -> None:
    """Fuel use -1 %/min: the tracker's error <= the RLS's in every record."""
    tr, rl = np.array(drift.tracker), np.array(drift.rls)
    assert np.all(tr <= rl), (tr, rl)


def test_drift_sigma_calibrated(drift) -> None:
    """RMS z against the current true tensor in [0.7, 1.5] over 20 seeds; no false change."""
    assert 0.7 <= drift.rms_z <= 1.5, drift.rms_z
    assert sum(drift.changes) <= 2


def test_update_cost_independent_of_memory() -> None:
    """One update is one small Kalman step: a 1000 s memory costs what a 10 s one does."""
    rec = simulate_truth(TruthCase(duration=20.0), [1])[0]
    cost = []
    for memory in (10.0, 1000.0):
        est = TrackingEstimator(window=memory)
        t0 = time.perf_counter()
        est.add_torque(rec.t_torque, rec.torque)
        est.add_gyro(rec.t_gyro, rec.omega)
        cost.append((time.perf_counter() - t0) / est.updates)
    assert cost[1] < 3.0 * cost[0] + 1e-3


def test_estimate_statuses_and_reset() -> None:
    """insufficient_data at start, ok with a covariance once started; reset forgets."""
    rec = simulate_truth(TruthCase(duration=8.0), [2])[0]
    est = TrackingEstimator(window=10.0)
    assert est.estimate().status == 'insufficient_data'
    est.add_torque(rec.t_torque, rec.torque)
    est.add_gyro(rec.t_gyro, rec.omega)
    res = est.estimate()
    assert res.status == 'ok', res.diagnostics.get('reason')
    assert res.method == 'tracking'
    assert np.allclose(res.inertia, rec.inertia, atol=0.02)
    assert res.covariance.shape == (6, 6)
    assert np.all(np.diag(res.covariance) > 0)
    est.reset()
    assert est.estimate().status == 'insufficient_data'


def test_diagonal_model_and_bias_run() -> None:
    """Other parameter sets: the diagonal model fixes the products at 0 (std 0)."""
    rec = simulate_truth(TruthCase(duration=8.0, inertia=np.diag([1.0, 1.2, 0.9])), [3])[0]
    est = TrackingEstimator(window=10.0, model='diagonal', torque_bias='on')
    est.add_torque(rec.t_torque, rec.torque)
    est.add_gyro(rec.t_gyro, rec.omega)
    res = est.estimate()
    assert res.status == 'ok'
    assert res.model == 'diagonal+bias'
    assert np.allclose(np.diag(res.inertia), [1.0, 1.2, 0.9], rtol=0.03)
    assert res.inertia_std[0, 1] == 0.0


@pytest.mark.parametrize('kw, msg', [({'window': 0.0}, 'window'), ({'model': 'x'}, 'model'),
                                     ({'block': -1.0}, 'block'),
                                     ({'change_level': 0.7}, 'change_level'),
                                     ({'torque_bias': 'maybe'}, 'torque_bias')])
def test_bad_options_are_one_line(kw, msg) -> None:
    with pytest.raises(ValueError, match=msg):
        TrackingEstimator(**kw)


def test_out_of_order_samples_refused() -> None:
    est = TrackingEstimator()
    est.add_gyro([1.0, 2.0], np.zeros((2, 3)))
    with pytest.raises(ValueError, match='not after'):
        est.add_gyro([1.5], np.zeros((1, 3)))


def test_bench_tracking_subcommand(capsys: pytest.CaptureFixture) -> None:
    """``bench tracking`` parses its options; an absurd memory is one line, exit 2."""
    from inertia_ros.cli import build_parser, main

    args = build_parser('bench').parse_args(['bench', 'tracking', '--seeds', '2',
                                             '--memory', '5'])
    assert (args.kind, args.seeds, args.memory) == ('tracking', 2, 5.0)
    assert main(['bench', 'tracking', '--memory', '0']) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and '--memory' in err, err


@pytest.mark.parametrize('stream', ['gyro', 'torque'])
def test_gap_reanchors_and_keeps_tracking(stream) -> None:
    """A 2 s hole in either stream: the filter re-anchors after it (counted), stays ok and
    accurate; gyro samples the held torque would have covered wrongly are dropped."""
    rec = simulate_truth(TruthCase(duration=20.0), [5])[0]
    keep_g = np.ones(len(rec.t_gyro), bool)
    keep_t = np.ones(len(rec.t_torque), bool)
    hole = lambda t: (t > 8.0) & (t < 10.0)  # noqa: E731
    if stream == 'gyro':
        keep_g &= ~hole(rec.t_gyro)
    else:
        keep_t &= ~hole(rec.t_torque)
    est = TrackingEstimator(window=10.0)
    tg, w = rec.t_gyro[keep_g], rec.omega[keep_g]
    tq, tau = rec.t_torque[keep_t], rec.torque[keep_t]
    for a in np.arange(0.0, 20.0, 0.5):
        sg, sq = (tg >= a) & (tg < a + 0.5), (tq >= a) & (tq < a + 0.5)
        est.add_torque(tq[sq], tau[sq])
        est.add_gyro(tg[sg], w[sg])
    res = est.estimate()
    assert est.gaps == 1
    assert not est.changes
    assert res.status == 'ok'
    assert np.linalg.norm(res.inertia - rec.inertia) / np.linalg.norm(rec.inertia) < 0.01
    if stream == 'torque':
        assert res.samples_dropped > 300


def test_memory_bounded_while_undetermined() -> None:
    """Rotation about one axis never determines the tensor: the start-up buffer stays
    bounded (insufficient_data with the reason), it does not grow with the record."""
    t = np.arange(0.0, 60.0, 0.005)
    w = np.column_stack([np.zeros_like(t), np.zeros_like(t), 0.3 + 0.01 * np.sin(t)])
    tq = np.arange(0.0, 60.0, 0.02)
    tau = np.column_stack([np.zeros_like(tq), np.zeros_like(tq), 0.01 * np.cos(tq)])
    est = TrackingEstimator(window=10.0)
    for a in range(60):
        est.add_torque(tq[(tq >= a) & (tq < a + 1)], tau[(tq >= a) & (tq < a + 1)])
        est.add_gyro(t[(t >= a) & (t < a + 1)], w[(t >= a) & (t < a + 1)])
    res = est.estimate()
    assert res.status == 'insufficient_data' and res.diagnostics['reason']
    kept = sum(len(x[0]) for x in est._warm)
    assert kept <= 5 * 2.0 * 200 + 400 and len(est._ts) <= 5 * 2.0 * 50 + 200


#: The reference simulator's default scene at 200/50 Hz (test_online_hold.SCENE).
HOLD_SCENE = TruthCase(amplitude=0.06, torque_noise=0.0012, omega0=(0.05, -0.03, 0.02),
                       duration=40.0)


def _feed_blocks(est, rec, block: float = 0.1):
    """Both streams in ``block``-second blocks, an estimate after each (as the node does)."""
    edges = np.arange(0.0, rec.t_gyro[-1] + 2 * block, block)
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        q = (rec.t_torque >= a) & (rec.t_torque < b)
        g = (rec.t_gyro >= a) & (rec.t_gyro < b)
        if q.any():
            est.add_torque(rec.t_torque[q], rec.torque[q])
        if g.any():
            est.add_gyro(rec.t_gyro[g], rec.omega[g])
        e = est.estimate()
    return e


@pytest.mark.parametrize('kind, chosen', [('continuous', 'linear'), ('zoh', 'zoh')])
def test_tracking_auto_hold_locks_the_hold_of_the_source(kind: str, chosen: str) -> None:
    """Issue 26: ``hold='auto'`` runs both holds' filters until the batch rule settles (the
    same significant choice over the latest half of at least 10 s, or the rule's choice at
    20 s), then keeps one: a torque continuous between its samples -> linear, a held one ->
    zoh (40 s, seeds 0-1; measured locked at 14-20 s), status ok, the estimate within 0.02
    sigma of the filter of that hold given explicitly (the twin's blocks are cut where its
    estimates were asked; measured 0.0035), |z| < 4.  On f0eb6ad ``hold='auto'`` was refused."""
    from inertia_ros.core.inertia import matrix_to_theta

    for rec in simulate_truth(HOLD_SCENE.with_(torque_kind=kind), range(2)):
        auto = TrackingEstimator(window=10.0, hold='auto')
        e = _feed_blocks(auto, rec)
        sel = e.diagnostics['hold_selection']
        assert sel['chosen'] == chosen == e.diagnostics['hold'] and sel['locked'], sel
        assert auto._choice is None and auto.hold == chosen       # the twin is dropped
        fixed = _feed_blocks(TrackingEstimator(window=10.0, hold=chosen), rec)
        assert e.status == fixed.status == 'ok', (e.status, fixed.status)
        np.testing.assert_array_less(np.abs(e.theta - fixed.theta), 0.02 * fixed.theta_std)
        z = (e.theta - matrix_to_theta(rec.inertia)) / e.theta_std
        assert np.max(np.abs(z)) < 4.0, z


def test_tracking_follows_a_payload_step_on_a_wheel_driven_body() -> None:
    """Issue 26: wheels without any other torque (the scene simulator's three reaction wheels,
    test_capability_matrix's scene, 30 s), the tensor +20 % at 12 s with the rate continuous:
    the tracker on the wheel momentum (``MomentumTrackingEstimator``, memory 5 s) finds the
    step within 0.5 s (twice: the second time the momentum's jump ``dI w`` too) and at the
    end reads the new tensor within 3 sigma (measured |z| <= 0.7, error 0.02 %), status ok,
    seeds 0-1.  On d5ad26d wheels were refused in tracking mode."""
    from test_capability_matrix import BASE, _wheel_inputs, _wheel_scene, feed

    from inertia_ros.core.estimation.momentum import Wheel
    from inertia_ros.core.estimation.recursive_momentum import MomentumTrackingEstimator
    from inertia_ros.core.inertia import matrix_to_theta
    from inertia_ros.core.scene import Scene
    from inertia_ros.core.simulation import simulate

    d = dict(_wheel_scene(), duration=30.0, inertia_change={
        'time': 12.0, 'inertia': [0.144, 0.12, 0.096, 0.0048, -0.0036, 0.0024]})
    sc = Scene.from_dict(d)
    ws = [Wheel(w.joint, w.axis, w.inertia) for w in sc.wheels.wheels]
    new = matrix_to_theta(sc.inertia_change.inertia)
    for seed in range(2):
        r = simulate(sc, seed)
        rec = {'tg': r.t_gyro, 'w': r.omega, 'tt': np.zeros(0), 'tau': np.zeros((0, 3)),
               'mom': True, 't_wheel': r.t_wheel, 'speed': r.wheel_speed,
               'inputs': lambda t, s: _wheel_inputs(t, s, ws)}
        est = MomentumTrackingEstimator(other_torque=False, window=5.0, **BASE)
        e = feed(est, rec)
        assert 1 <= len(est.changes) <= 2 and 12.0 <= min(est.changes), est.changes
        assert max(est.changes) < 12.5, est.changes
        z = (e.theta - new) / e.theta_std
        assert e.status == 'ok' and np.all(np.abs(z) < 3.0), (e.status, z)


def test_tracking_states_the_wheel_inertias() -> None:
    """Issue 26: the wheels' stated inertia sigmas (5 %, ``names``) are states of the tracker,
    considered at their prior: on the capability matrix's wheel records with each wheel's
    inertia off by +-1 stated sigma (signs +, -, +-), every diagonal sigma grows at least
    4x (measured 4.9-12.9x), each input's ``theta_change`` is recorded and the RMS z of the
    six elements over seeds 0-2 falls from 4.2 (unstated, ``model_mismatch``; 4.4 while the
    filter's noise held the wheels' record-mean walk, issue 27) to 3.0 (measured; not yet
    in [0.5, 2]: the considered inputs are not profiled as the recursive mode does).  It was
    2.6 while the gyro noise was estimated low (issue 27, session 6): seed 0 was then
    ``model_mismatch`` on its average NIS and its sigma widened; with the unbiased noise it
    is ``ok`` (the stated sigmas cover the wheels' error) at the considered sigma, |z| 4.3."""
    from test_capability_matrix import BASE, IDX, _wheel_inputs, _wheel_scene, feed, records

    from inertia_ros.core.estimation.momentum import Wheel
    from inertia_ros.core.estimation.recursive_momentum import MomentumTrackingEstimator
    from inertia_ros.core.scene import Scene

    wheels = Scene.from_dict(_wheel_scene()).wheels.wheels
    z = {0.0: [], 0.05: []}
    for i, rec in enumerate(records('wheels')):
        out = {}
        for std in z:
            sign = (1.0, -1.0, 1.0 if i % 2 == 0 else -1.0)
            ws = [Wheel(w.joint, w.axis, w.inertia * (1 + sign[j] * 0.05), w.inertia * std)
                  for j, w in enumerate(wheels)]
            names = tuple(f'inertia:{w.joint}' for w in ws) if std else ()
            est = MomentumTrackingEstimator(names=names, other_torque=False, window=1000.0,
                                            **BASE)
            out[std] = e = feed(est, dict(rec, inputs=lambda t, s, ws=ws: _wheel_inputs(
                t, s, ws)))
            z[std].append((e.theta - rec['truth'][IDX]) / e.theta_std)
        rec = out[0.05].diagnostics['input_uncertainty']
        assert set(rec['inputs']) == set(names)       # the other modes' record form
        assert rec['theta_std_added'].shape == (6,) and np.all(rec['theta_std_added'][:3] > 0)
        assert np.all(out[0.05].theta_std[:3] >= 4.0 * out[0.0].theta_std[:3])
    rms = {std: float(np.sqrt(np.mean(np.square(v)))) for std, v in z.items()}
    assert rms[0.05] < 3.2 and rms[0.05] < 0.75 * rms[0.0], rms


def test_tracking_hold_auto_with_stated_wheels_and_an_empty_first_block() -> None:
    """Two crashes of hold 'auto' (the node's default) on the tracker: with stated wheel
    inertias (``names``) the hold judge was built without them and the first momentum
    block raised a reshape ValueError; an empty first gyro block raised IndexError.  Both
    now run: the stated wheels' record is ok with the hold judged, the empty block leaves
    the estimate ``insufficient_data``."""
    from test_capability_matrix import BASE, _wheel_inputs, _wheel_scene, feed, records

    from inertia_ros.core.estimation.momentum import Wheel
    from inertia_ros.core.estimation.recursive_momentum import MomentumTrackingEstimator
    from inertia_ros.core.scene import Scene

    ws = [Wheel(w.joint, w.axis, w.inertia, 0.05 * w.inertia)
          for w in Scene.from_dict(_wheel_scene()).wheels.wheels]
    est = MomentumTrackingEstimator(names=tuple(f'inertia:{w.joint}' for w in ws),
                                    window=1000.0, **dict(BASE, hold='auto'))
    e = feed(est, dict(records('wheels_torque')[0],
                       inputs=lambda t, s: _wheel_inputs(t, s, ws)))
    assert e.status == 'ok', e.status
    assert e.diagnostics['hold_selection']['statistic'] is not None
    empty = TrackingEstimator(hold='auto')
    empty.add_gyro(np.zeros(0), np.zeros((0, 3)))
    empty.add_torque(np.zeros(0), np.zeros((0, 3)))
    assert empty.estimate().status == 'insufficient_data'
