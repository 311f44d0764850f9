"""``hold='auto'`` decides held against linear torque by evidence (issue 27, item 2).

The rule (:func:`inertia_ros.core.estimation.selection.select_hold`): the higher likelihood,
the lower residual excess of the two holds' whole-record fits; then the adequacy tests (a
held fit that fails them is left for a linear one that passes them, and the other way).
Records from the independent RK4 simulator :mod:`inertia_ros.bench.truth_sim` with the
default scene's body and excitation (multisine of RMS 0.06 N m per axis, torque noise 2 % of
it, 200 Hz gyro with 0.002 rad/s noise, 50 Hz torque), the applied torque either held between
its samples (a command) or continuous (varying smoothly, nearly linearly, between them).
Before this rule a fixed margin (linear's residual excess 10 % below the held one) kept zoh
on 8 of 10 continuous records and the window test then said ``model_mismatch``; the Vuong
test on per-window likelihoods that replaced it chose linear on 7 of 40 held 5 s records
(the node's seed 28 ok at |z| 5.1).
"""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from inertia_ros.bench.truth_sim import TruthCase, simulate_truth
from inertia_ros.core.estimation import estimate
from inertia_ros.core.estimation.hold_choice import hold_by_adequacy
from inertia_ros.core.estimation.recursive import RecursiveEstimator
from inertia_ros.core.estimation.selection import HOLD_RULE, select_hold
from inertia_ros.core.inertia import matrix_to_theta

#: The default scene (config/scenes/default.yaml) on the reference simulator.
SCENE = TruthCase(amplitude=0.06, torque_noise=0.0012, omega0=(0.05, -0.03, 0.02))


def _runs(kind: str, seeds: range, duration: float) -> list[tuple[object, np.ndarray]]:
    """(estimate with every option at its default, z = error / sigma (6,)) per seed."""
    out = []
    for rec in simulate_truth(SCENE.with_(torque_kind=kind, duration=duration), seeds):
        e = estimate(rec.t_gyro, rec.omega, rec.t_torque, rec.torque)
        z = (e.theta - matrix_to_theta(rec.inertia)) / e.theta_std
        out.append((e, z))
    return out


def test_rule_picks_the_lower_excess() -> None:
    """The hold whose fit leaves the lower residual excess; zoh on a tie or without fits."""
    chosen, rec = select_hold(1.05, 1.0)                  # the held fit is worse
    assert chosen == 'linear' == rec['chosen'] and rec['test'] == 'likelihood'
    assert rec['statistic'] == pytest.approx(np.log(1.0 / 1.05)) and rec['rss_ratio'] < 1.0
    assert rec['rule'] == HOLD_RULE
    assert select_hold(1.0, 1.002)[0] == 'zoh'            # the linear fit is worse
    assert select_hold(1.0, 1.0)[0] == 'zoh'              # a tie
    for bad in ((None, 1.0), (1.0, float('nan')), (0.0, 1.0)):
        chosen, rec = select_hold(*bad)
        assert chosen == 'zoh' and rec['statistic'] is None and 'not compared' in rec['reason']


@pytest.mark.parametrize('kind, want', [('zoh', 'zoh'), ('continuous', 'linear')])
def test_short_records_pick_the_true_hold(kind: str, want: str) -> None:
    """5 s records, seeds 20-39 (the Vuong rule chose linear on 7 of 40 held ones, the
    node's seed 28 ok at |z| 5.1): the true hold in at least 19 of 20, batch defaults and
    the node's estimator alike, and every ok record within 4 sigma."""
    from inertia_ros.bench.honesty import _NODE_DEFAULTS, feed_online
    recs = simulate_truth(SCENE.with_(torque_kind=kind, duration=5.0), range(20, 40))
    for path in ('api', 'node'):
        right = 0
        for rec in recs:
            if path == 'api':
                e = estimate(rec.t_gyro, rec.omega, rec.t_torque, rec.torque)
            else:
                e = feed_online(RecursiveEstimator(**_NODE_DEFAULTS, reselect_every=10,
                                                   defer_adequacy=True), rec, 10.0)
            right += e.diagnostics['hold'] == want
            z = (e.theta - matrix_to_theta(rec.inertia)) / e.theta_std
            assert e.status != 'ok' or np.max(np.abs(z)) < 4.0, (path, rec.seed, z)
        assert right >= 19, (path, right)


def test_continuous_torque_picks_linear() -> None:
    """Continuous torque, 20 s, 3 seeds, CLI defaults: linear chosen by the likelihoods
    (the linear excess at least 1 % below the held one), status ok, max |z| < 4."""
    for e, z in _runs('continuous', range(3), 20.0):
        sel = e.diagnostics['hold_selection']
        assert sel['chosen'] == 'linear' == e.diagnostics['hold'], sel
        assert sel['statistic'] < -0.01 and sel['test'] == 'likelihood', sel
        assert 'adequacy' not in sel, sel
        assert e.status == 'ok', e.diagnostics.get('reason')
        assert np.max(np.abs(z)) < 4.0, z


def test_adequacy_overrides_the_likelihoods() -> None:
    """Held fit inadequate and linear adequate: linear; both inadequate: the held result."""
    def est(ok: bool) -> SimpleNamespace:
        return SimpleNamespace(diagnostics={'adequacy': {'ok': ok}})

    held = est(False)
    for lin_ok, want in ((True, 'linear'), (False, 'zoh')):
        lin = est(lin_ok)
        record: dict = {}
        chosen, got = hold_by_adequacy(lambda *a, lin=lin, **k: lin, {'linear': est(True)},
                                        held, record)
        assert chosen == want and got is (lin if lin_ok else held)
        assert record['adequacy']['zoh_ok'] is False and record['adequacy']['linear_ok'] is lin_ok
    adequate = est(True)           # the held fit passes: linear is not even run
    assert hold_by_adequacy(None, {}, adequate, {}) == ('zoh', adequate)


def test_held_torque_keeps_zoh_and_ml() -> None:
    """Held torque, 20 s, 3 seeds: zoh kept, so ml refines it (method ml), status ok."""
    for e, z in _runs('zoh', range(3), 20.0):
        sel = e.diagnostics['hold_selection']
        assert sel['chosen'] == 'zoh' == e.diagnostics['hold'], sel
        assert e.status == 'ok' and e.method == 'ml', (e.status, e.diagnostics.get('ml'))
        assert np.max(np.abs(z)) < 4.0, z


@pytest.mark.parametrize('fault', [
    {'gyro_bias': (0.01, -0.01, 0.01)},
    {'t_change': 15.0, 'change': 0.2},
])
def test_faults_stay_flagged_under_either_hold(fault: dict) -> None:
    """Continuous torque plus a fault (gyro bias, +20 % payload at 15 s), 30 s, 2 seeds:
    model_mismatch whichever hold is chosen (the adequacy step never turns a fault into ok:
    both holds fail the tests)."""
    case = SCENE.with_(torque_kind='continuous', duration=30.0, **fault)
    for rec in simulate_truth(case, range(2)):
        e = estimate(rec.t_gyro, rec.omega, rec.t_torque, rec.torque)
        assert e.status == 'model_mismatch', (e.status, e.diagnostics['hold_selection'])


@pytest.mark.slow
@pytest.mark.parametrize('kind', ['continuous', 'zoh'])
def test_ok_fraction_and_calibration(kind: str) -> None:
    """10 seeds, 60 s, CLI defaults: ok in >= 9 (continuous) / all 10 (held: no false alarm),
    RMS z over the six elements in [0.7, 1.5]."""
    runs = _runs(kind, range(10), 60.0)
    ok = sum(e.status == 'ok' for e, _ in runs)
    rms = float(np.sqrt(np.mean(np.square([z for _, z in runs]))))
    assert ok >= (9 if kind == 'continuous' else 10), [e.status for e, _ in runs]
    assert 0.7 <= rms <= 1.5, rms


def test_inertial_disturbance_is_modelled_with_the_right_hold() -> None:
    """Continuous torque plus a torque of 0.01 N m fixed in inertial axes, 30 s, seeds 0-3:
    modelled by default (``inertial_torque='auto'``), the holds compared again with it
    (without it the unmodelled torque swamped the comparison: zoh and ``model_mismatch`` in
    3 of 6 at |z| < 2; before this rule in all 6): linear, ok, the torque within 3 % and
    max |z| < 4."""
    case = SCENE.with_(torque_kind='continuous', duration=30.0,
                       disturbance=(0.01, 0.01, -0.01), disturbance_kind='inertial')
    for rec in simulate_truth(case, range(4)):
        e = estimate(rec.t_gyro, rec.omega, rec.t_torque, rec.torque)
        assert e.status == 'ok' and e.diagnostics['hold'] == 'linear', (
            e.status, e.diagnostics['hold_selection'])
        np.testing.assert_allclose(e.inertial_torque, [0.01, 0.01, -0.01], rtol=0.03)
        z = (e.theta - matrix_to_theta(rec.inertia)) / e.theta_std
        assert np.max(np.abs(z)) < 4.0, z
