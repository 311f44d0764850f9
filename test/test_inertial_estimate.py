"""``estimate(..., inertial_torque=...)``: a torque fixed in inertial axes as a nuisance of the
batch ``integral`` methods, chosen with the torque bias by joint Wald tests (issue 27).

On the reference simulator's 5 s disturbance records (0.01 N m per axis fixed in inertial
axes) the package today reports 35 of 40 ``model_mismatch`` at 3.3 % error and 4 ``ok``
beyond 4 sigma (seed 31 at 6.0); with ``inertial_torque='auto'`` all 40 ``ok`` at 0.40 %,
RMS z 0.97, none beyond 4 sigma; without the disturbance 38 of 40 keep no disturbance term
(2 both) and nothing changes in kind."""
from __future__ import annotations

import numpy as np
import pytest

from inertia_ros.bench.honesty import CASES
from inertia_ros.bench.truth_sim import simulate_truth
from inertia_ros.core.estimation import estimate
from inertia_ros.core.tensor import THETA_COLS, THETA_ROWS

D_TRUE = np.array([0.01, 0.01, -0.01])


def _records(scene: str, seeds: list[int] | range, duration: float = 5.0) -> list:
    case = CASES['disturbance'].truth.with_(duration=duration)
    if scene == 'zero':
        case = case.with_(disturbance=(0.0, 0.0, 0.0))
    return simulate_truth(case, seeds)


def _run(rec, **kw):
    e = estimate(rec.t_gyro, rec.omega, rec.t_torque, rec.torque, method='integral', **kw)
    th = e.inertia[THETA_ROWS, THETA_COLS]
    z = (th - rec.inertia_end[THETA_ROWS, THETA_COLS]) / e.inertia_std[THETA_ROWS, THETA_COLS]
    err = np.linalg.norm(e.inertia - rec.inertia_end) / np.linalg.norm(rec.inertia_end)
    return e, z, err


def test_auto_fits_the_inertial_torque_on_the_disturbance_records() -> None:
    rows = [_run(r, inertial_torque='auto') for r in _records('inertial', range(10))]
    chosen = [e.diagnostics['disturbance']['chosen'] for e, _, _ in rows]
    assert chosen.count('inertial') >= 8 and chosen.count('none') == 0, chosen
    assert sum(e.status == 'ok' for e, _, _ in rows) >= 9
    assert not any(e.status == 'ok' and np.abs(z).max() > 4.0 for e, z, _ in rows)
    assert np.median([err for *_, err in rows]) < 0.008          # 3.3 % without the term
    z = np.array([z for _, z, _ in rows])
    assert 0.7 < np.sqrt(np.mean(z ** 2)) < 1.35
    for e, _, _ in rows:
        if e.model == 'full+inertial':                   # (with the bias: collinear)
            d, sd = e.inertial_torque, e.diagnostics['inertial_torque_std']
            assert np.all(np.abs(d - D_TRUE) < 4.0 * sd) and np.all(sd < 5e-3)


def test_short_disturbance_seed_31_is_caught_with_the_inertial_torque() -> None:
    """Seed 31 of the 5 s disturbance scene: ``ok`` at 3.8 % and |z| 6.0 without the term
    (``'off'``; the default before session 9); with it (the default ``'auto'``) ``ok`` at
    0.25 %, |z| 1.8."""
    rec = _records('inertial', [31])[0]
    e0, z0, _ = _run(rec, inertial_torque='off')
    assert e0.status == 'ok' and np.abs(z0).max() > 5.0            # the fault without it
    e, z, err = _run(rec)
    assert e.status == 'ok' and np.abs(z).max() < 3.0 and err < 0.01
    assert e.model == 'full+inertial'
    assert e.diagnostics['disturbance']['tests']['inertial_given_body']['kept']


def test_auto_keeps_no_term_without_a_disturbance() -> None:
    rows = [_run(r, inertial_torque='auto') for r in _records('zero', range(10))]
    chosen = [e.diagnostics['disturbance']['chosen'] for e, _, _ in rows]
    assert chosen.count('none') >= 8, chosen
    assert all(e.status == 'ok' for e, _, _ in rows)
    z = np.array([z for _, z, _ in rows])
    assert 0.7 < np.sqrt(np.mean(z ** 2)) < 1.35


def test_auto_is_the_default_and_off_leaves_the_term_out() -> None:
    rec = _records('inertial', [4])[0]
    default = estimate(rec.t_gyro, rec.omega, rec.t_torque, rec.torque, method='integral')
    auto = estimate(rec.t_gyro, rec.omega, rec.t_torque, rec.torque, method='integral',
                    inertial_torque='auto')
    off = estimate(rec.t_gyro, rec.omega, rec.t_torque, rec.torque, method='integral',
                   inertial_torque='off')
    assert np.array_equal(default.inertia, auto.inertia)
    assert np.array_equal(default.inertia_std, auto.inertia_std)
    assert default.model.endswith('+inertial') and default.inertial_torque is not None
    assert 'disturbance' not in off.diagnostics and '+inertial' not in off.model
    assert off.inertial_torque is None and 'inertial_torque_std' not in off.diagnostics


def test_on_reports_the_inertial_torque_and_its_sigma() -> None:
    rec = _records('inertial', [5])[0]
    e = estimate(rec.t_gyro, rec.omega, rec.t_torque, rec.torque, method='integral_ls',
                 inertial_torque='on', torque_bias='off', model='full')
    assert e.model == 'full+inertial' and e.torque_bias is None
    assert e.inertial_torque.shape == (3,)
    assert e.diagnostics['inertial_torque_std'].shape == (3,)
    assert e.diagnostics['disturbance']['tests'] == {}
    assert e.diagnostics['disturbance']['chosen'] == 'inertial'


@pytest.mark.parametrize('method', ['integral_sliding', 'differential_fd', 'differential_sg'])
def test_other_methods_refuse_on_and_run_auto_without_it(method: str) -> None:
    rec = _records('zero', [0], duration=2.0)[0]
    with pytest.raises(ValueError, match=r"^inertial_torque: 'on' needs method auto, integral, "
                                         r"integral_ls, ml, filtered \(the other") as exc:
        estimate(rec.t_gyro, rec.omega, rec.t_torque, rec.torque, method=method,
                 inertial_torque='on')
    assert '\n' not in str(exc.value)
    e = estimate(rec.t_gyro, rec.omega, rec.t_torque, rec.torque, method=method)
    assert e.inertial_torque is None and '+inertial' not in e.model
    assert 'no inertial torque term' in e.diagnostics['disturbance']['skipped']


def test_a_bad_value_is_refused() -> None:
    rec = _records('zero', [0], duration=2.0)[0]
    with pytest.raises(ValueError, match='inertial_torque: must be one of off, auto, on'):
        estimate(rec.t_gyro, rec.omega, rec.t_torque, rec.torque, method='integral',
                 inertial_torque='yes')


@pytest.mark.parametrize(('seed', 'hold'), [(36, 'zoh'), (134, 'zoh'), (184, 'zoh'),
                                          (10, 'zoh')])
def test_the_linear_runs_keep_the_held_runs_inertial_choice(seed: int, hold: str) -> None:
    """Zero-control records (held torque, no disturbance).  Selected anew on the linear hold,
    a body bias and an inertial torque in opposite directions absorbed the wrong hold's
    misfit: seed 36 chose linear in the comparison (b = (-0.065, 0.044, -0.014), d = (0.070,
    -0.034, 0.013) N m, joint p 4e-16), seed 184's final linear run passed the tests that
    send the package back to zoh (3.9 % against 0.5 %); seed 134 went linear when the linear
    run kept the held run's bias too.  Now each ends as the package without the option:
    zoh with no disturbance and no false disturbance report (seed 10: the Vuong rule picked
    linear at p 1e-7 on this held torque; the likelihoods pick zoh)."""
    rec = _records('zero', [seed])[0]
    e, _, _ = _run(rec, inertial_torque='auto')
    assert e.diagnostics['hold'] == hold and e.model == 'full'
    assert e.diagnostics['disturbance']['chosen'] in ('none', None)
    off = estimate(rec.t_gyro, rec.omega, rec.t_torque, rec.torque, method='integral')
    assert off.diagnostics['hold'] == hold


@pytest.mark.parametrize(('gap_s', 'fitted'), [(0.03, True), (0.1, True), (0.5, False)])
def test_gyro_gaps_carry_the_attitude_only_when_the_bridge_is_safe(gap_s: float,
                                                                   fitted: bool) -> None:
    """Seed 31 with the gyro samples of [2, 2 + gap) s removed: the attitude is carried over
    the gap at the mean rate of its end samples while ``|dw| h / 2`` stays under
    ATTITUDE_BRIDGE_RAD (measured 1.2e-4 and 1.3e-3 rad: inertial torque fitted, 0.42 % and
    0.46 %); over 0.5 s the bound is 0.038 rad: not fitted, and said so."""
    from inertia_ros.core.estimation.options import ATTITUDE_BRIDGE_RAD
    rec = _records('inertial', [31])[0]
    keep = ~((rec.t_gyro >= 2.0) & (rec.t_gyro < 2.0 + gap_s))
    e = estimate(rec.t_gyro[keep], rec.omega[keep], rec.t_torque, rec.torque,
                 method='integral', inertial_torque='auto')
    att, dist = e.diagnostics['attitude'], e.diagnostics['disturbance']
    assert att['gaps'] == 1 and (att['bridge_error_rad'] <= ATTITUDE_BRIDGE_RAD) == fitted
    if fitted:
        assert dist['chosen'] == 'inertial' and e.model == 'full+inertial'
        err = np.linalg.norm(e.inertia - rec.inertia_end) / np.linalg.norm(rec.inertia_end)
        assert err < 0.01
    else:
        assert dist['chosen'] is None and 'too long to carry the attitude' in dist['skipped']
        assert '+inertial' not in e.model


def test_a_stated_hold_keeps_the_term_only_when_the_tests_pass() -> None:
    """``hold='zoh'`` given, model-conforming 5 s record (the honest-status scene), seed 33:
    a body bias and an inertial torque nearly cancelling failed the adequacy tests at
    13.8 % where the fit without them is ok at 0.9 %; now the fit without them, and the
    diagnostics say why."""
    from inertia_ros.bench.truth_sim import TruthCase
    scene = TruthCase(amplitude=0.06, torque_noise=0.0012, omega0=(0.05, -0.03, 0.02))
    rec = simulate_truth(scene.with_(duration=5.0), [33])[0]
    e = estimate(rec.t_gyro, rec.omega, rec.t_torque, rec.torque, hold='zoh')
    err = np.linalg.norm(e.inertia - rec.inertia) / np.linalg.norm(rec.inertia)
    assert e.status == 'ok' and e.inertial_torque is None and err < 0.02, (e.status, err)
    assert 'left out' in e.diagnostics['disturbance']['rule']
