"""The exciter's safety and stopping rules (issue 28 part 2), without ROS.

Every rule of core/exciter_rules.py on small hand-made cases: what is commanded, in which
state and why.  Tolerances: torques exact to 1e-12 N m (the rules only add, clip and zero).
"""
from __future__ import annotations

import numpy as np
import pytest

from conftest import ROOT
from inertia_ros.core.exciter_rules import (
    ExciterLimits,
    ExciterRules,
    TorqueSchedule,
    predicted_rate,
    principal_rel_std,
)
from inertia_ros.core.simulation import simulate
from inertia_ros.io.scene_file import load_scene

I3 = np.diag([1.0, 1.2, 0.9])
DT = 0.02


def rules(**kw) -> ExciterRules:
    base = dict(max_torque=0.1, max_slew=1.0, max_rate=1.0, target_rel_std=0.02,
                timeout=100.0, estimator_timeout=5.0, command_period=DT, stall_window=10.0)
    base.update(kw)
    return ExciterRules(ExciterLimits(**base), I3)


def run(r: ExciterRules, planned, t0=0.0, n=1, omega=(0.0, 0.0, 0.0)):
    """n steps of DT with a fresh gyro sample each; the last command."""
    cmd = None
    for k in range(n):
        t = t0 + k * DT
        r.on_gyro(t, np.asarray(omega, float))
        cmd = r.step(t, np.asarray(planned, float))
    return cmd


# --------------------------------------------------------------------------- safety
def test_waits_for_the_first_gyro_sample():
    r = rules()
    cmd = r.step(0.0, np.array([0.05, 0, 0]))
    assert cmd.state == 'waiting' and np.all(cmd.torque == 0.0)
    assert r.t_start is None


def test_torque_over_the_limit_holds_zero_and_names_the_axis():
    """Not clipped: a command over max_torque on one axis zeroes every axis."""
    r = rules(max_slew=100.0)
    cmd = run(r, [0.05, -0.2, 0.01], n=3)
    assert cmd.state == 'holding'
    np.testing.assert_array_equal(cmd.torque, np.zeros(3))
    assert 'torque limit' in cmd.reason and ' y ' in cmd.reason and 'max_torque 0.1' in cmd.reason
    cmd = run(r, [0.05, -0.09, 0.01], t0=3 * DT)   # back within the limit: commanded as is
    assert cmd.state == 'exciting' and cmd.reason == ''
    np.testing.assert_allclose(cmd.torque, [0.05, -0.09, 0.01], atol=1e-12)


def test_slew_rate_limits_every_change_also_towards_zero():
    r = rules(max_slew=1.0)         # 0.02 N m per 20 ms step
    outs = [run(r, [0.1, -0.1, 0.0], t0=k * DT).torque for k in range(8)]
    np.testing.assert_allclose(outs[0], [0.02, -0.02, 0.0], atol=1e-12)
    np.testing.assert_allclose(outs[4], [0.1, -0.1, 0.0], atol=1e-12)
    # an over-limit plan: the hold at zero ramps down at the same slew rate
    outs += [run(r, [0.5, 0.0, 0.0], t0=(8 + k) * DT).torque for k in range(8)]
    steps = np.abs(np.diff(np.array(outs), axis=0))
    assert steps.max() <= 1.0 * DT + 1e-12
    np.testing.assert_allclose(outs[-1], np.zeros(3), atol=1e-12)


def test_random_plans_never_exceed_torque_or_slew():
    rng = np.random.default_rng(3)
    r = rules(max_torque=0.1, max_slew=2.0, max_rate=50.0)
    prev, t, held = np.zeros(3), 0.0, 0
    for _ in range(2000):
        dt = DT * rng.uniform(0.5, 1.5)
        t += dt
        r.on_gyro(t, rng.normal(0, 0.1, 3))
        r.on_sigma(t, 0.5 * np.exp(-0.01 * t))
        cmd = r.step(t, rng.uniform(-0.15, 0.15, 3))
        assert np.max(np.abs(cmd.torque)) <= 0.1 + 1e-12
        if prev is not None:
            assert np.max(np.abs(cmd.torque - prev)) <= 2.0 * dt + 1e-12
        prev, held = cmd.torque, held + (cmd.state == 'holding')
    assert 500 < held < 1500 and not r.stopped     # about 1 plan in 2 is over the limit


def test_rate_limit_holds_zero_brakes_and_resumes_under_the_band():
    r = rules(max_rate=0.3, max_slew=100.0, rate_hysteresis=0.8)
    # 0.29 rad/s about x, a torque that speeds it up: predicted over 0.3 -> hold zero
    cmd = run(r, [0.1, 0.0, 0.0], omega=[0.299, 0.0, 0.0])
    assert cmd.state == 'holding' and 'rate limit' in cmd.reason
    np.testing.assert_array_equal(cmd.torque, np.zeros(3))
    # a torque about y would still raise |omega|: held while above the band (0.24)
    cmd = run(r, [0.0, 0.1, 0.0], t0=DT, omega=[0.27, 0.0, 0.0])
    assert cmd.state == 'holding'
    # a braking command passes
    cmd = run(r, [-0.05, 0.0, 0.0], t0=2 * DT, omega=[0.27, 0.0, 0.0])
    assert cmd.state == 'exciting'
    np.testing.assert_allclose(cmd.torque, [-0.05, 0, 0], atol=1e-12)
    # under the band the plan is commanded again
    cmd = run(r, [0.0, 0.1, 0.0], t0=3 * DT, omega=[0.2, 0.0, 0.0])
    assert cmd.state == 'exciting'
    np.testing.assert_allclose(cmd.torque, [0.0, 0.1, 0.0], atol=1e-12)


def test_rate_prediction_counts_the_ramp_down_and_the_margin():
    """|omega| 0.25 under 0.1 N m about x of I_xx = 1: one 20 ms period alone adds 0.002 rad/s
    but ramping down at 0.1 N m/s takes 1 s more (0.05 rad/s): held at max_rate 0.28."""
    w = np.array([0.25, 0.0, 0.0])
    assert predicted_rate(w, [0.1, 0, 0], I3, DT, 0.0) == pytest.approx(0.252, abs=1e-9)
    assert predicted_rate(w, [0.1, 0, 0], I3, DT, 0.5) == pytest.approx(0.253, abs=1e-9)
    fast = rules(max_rate=0.28, max_slew=100.0)
    assert run(fast, [0.1, 0, 0], omega=w).state == 'exciting'
    slow = rules(max_rate=0.28, max_slew=0.1)
    run(slow, [0.1, 0, 0], omega=[0.0, 0.0, 0.0], n=60)      # ramped up to 0.1 N m
    cmd = run(slow, [0.1, 0, 0], t0=60 * DT, omega=w)
    assert cmd.state == 'holding' and 'rate limit' in cmd.reason


def test_stale_gyro_holds_zero():
    r = rules(max_slew=100.0, gyro_timeout=0.5)
    run(r, [0.05, 0, 0])
    cmd = r.step(0.6, np.array([0.05, 0, 0]))
    assert cmd.state == 'holding' and 'no gyro' in cmd.reason
    np.testing.assert_array_equal(cmd.torque, np.zeros(3))


# --------------------------------------------------------------------------- stops
def assert_stopped_for_good(r: ExciterRules, reason: str, t: float):
    cmd = r.step(t, np.array([0.05, 0.05, 0.05]))
    assert cmd.state == 'stopped' and r.stop_reason == reason, (cmd, r.stop_reason)
    np.testing.assert_array_equal(cmd.torque, np.zeros(3))
    r.on_gyro(t + 1, np.zeros(3))
    r.on_sigma(t + 1, 1e-9)          # nothing brings it back
    later = r.step(t + 1, np.array([0.05, 0.05, 0.05]))
    assert later.state == 'stopped' and r.stop_reason == reason
    np.testing.assert_array_equal(later.torque, np.zeros(3))


def test_stops_at_the_target_sigma():
    r = rules(max_slew=100.0)
    run(r, [0.05, 0, 0])
    r.on_sigma(0.5, 0.021)
    assert run(r, [0.05, 0, 0], t0=0.5).state == 'exciting'
    r.on_sigma(0.6, 0.019)
    assert_stopped_for_good(r, 'target_reached', 0.62)
    assert '0.019' in r.stop_detail


def test_stops_at_the_timeout():
    r = rules(timeout=2.0, estimator_timeout=100.0)
    run(r, [0.01, 0, 0], n=99)                      # 1.96 s
    assert not r.stopped
    assert_stopped_for_good(r, 'timeout', 2.0)


def test_stops_when_the_estimator_disappears():
    r = rules(estimator_timeout=1.0)
    for k in range(150):                            # 3 s with a covariance every 0.5 s
        t = k * DT
        if k % 25 == 0:
            r.on_sigma(t, 0.5 - 0.01 * k / 25)
        run(r, [0.01, 0, 0], t0=t)
    assert not r.stopped
    run(r, [0.01, 0, 0], t0=150 * DT, n=60)         # then silence: 2.98 - 3.0 + ... > 1 s
    assert r.stop_reason == 'estimator_lost' and 'no covariance for' in r.stop_detail
    assert_stopped_for_good(r, 'estimator_lost', 5.0)


def test_an_estimator_that_never_answers_is_lost_too():
    r = rules(estimator_timeout=1.0)
    run(r, [0.01, 0, 0], n=52)
    assert r.stop_reason == 'estimator_lost' and 'no covariance yet' in r.stop_detail


def test_stops_on_a_reset():
    r = rules()
    run(r, [0.01, 0, 0])
    r.on_reset(0.1, 'the estimator reset (service call)')
    assert_stopped_for_good(r, 'reset', 0.12)
    assert 'service call' in r.stop_detail


def test_stops_when_the_sigma_stops_improving():
    r = rules(stall_window=2.0, estimator_timeout=10.0)
    falling = rules(stall_window=2.0, estimator_timeout=10.0)
    for k in range(250):                            # 5 s, a covariance every 0.1 s
        t = k * DT
        if k % 5 == 0:
            r.on_sigma(t, 0.10 if t > 1.0 else 0.2 - 0.1 * t)   # flat after 1 s
            falling.on_sigma(t, 0.2 * np.exp(-0.05 * t))        # 5 %/s: > 2 % per window
        run(r, [0.01, 0, 0], t0=t)
        run(falling, [0.01, 0, 0], t0=t)
    assert r.stop_reason == 'not_improving'
    assert not falling.stopped


def test_a_reassessed_sigma_starts_a_new_stall_stretch():
    """The live estimator switching model or hold raises its sigma once (evidence never
    falls): the stall is judged from there, so a converging loop is not stopped, while a
    sigma flat after the jump still stops as not_improving."""
    jumped = rules(stall_window=2.0, estimator_timeout=10.0)
    flat = rules(stall_window=2.0, estimator_timeout=10.0)
    for k in range(250):                            # 5 s, a covariance every 0.1 s
        t = k * DT
        if k % 5 == 0:
            base = 0.2 * np.exp(-0.05 * t)          # 5 %/s: > 2 % per window
            jumped.on_sigma(t, base * (1.25 if t >= 1.5 else 1.0))   # a switch at 1.5 s
            flat.on_sigma(t, 0.1 if t < 1.5 else 0.13)               # jump, then flat
        run(jumped, [0.01, 0, 0], t0=t)
        run(flat, [0.01, 0, 0], t0=t)
    assert not jumped.stopped, jumped.stop_detail
    assert flat.stop_reason == 'not_improving'


def test_limits_are_checked_with_one_line_naming_the_field():
    for field, bad in (('max_torque', 0.0), ('max_slew', -1.0), ('max_rate', float('nan')),
                       ('rate_hysteresis', 1.0), ('rate_margin', 2.0)):
        kw = dict(max_torque=0.1, max_slew=1.0, max_rate=1.0)
        kw[field] = bad
        with pytest.raises(ValueError, match=field) as err:
            ExciterLimits(**kw)
        assert '\n' not in str(err.value)
    with pytest.raises(ValueError, match='positive definite'):
        ExciterRules(ExciterLimits(0.1, 1.0, 1.0), np.diag([1.0, -1.0, 1.0]))


# --------------------------------------------------------------------------- sigma, plan
def test_principal_rel_std_matches_monte_carlo():
    """First-order sigma of the principal moments against 4000 perturbed tensors (5 %)."""
    rng = np.random.default_rng(0)
    inertia = np.array([[1.0, 0.05, -0.03], [0.05, 1.2, 0.02], [-0.03, 0.02, 0.9]])
    a = rng.normal(size=(6, 6)) * 1e-3
    cov = a @ a.T
    lam, v = np.linalg.eigh(inertia)
    rel = principal_rel_std(cov, lam, v)
    theta = rng.multivariate_normal([1.0, 1.2, 0.9, 0.05, -0.03, 0.02], cov, 4000)
    mats = np.stack([[[t[0], t[3], t[4]], [t[3], t[1], t[5]], [t[4], t[5], t[2]]]
                     for t in theta])
    mc = np.linalg.eigvalsh(mats).std(axis=0) / lam
    np.testing.assert_allclose(rel, mc, rtol=0.05)
    # diagonal covariance, identity axes: sqrt(var)/moment
    np.testing.assert_allclose(principal_rel_std(np.diag([4e-4, 1e-4, 0, 0, 0, 0]),
                                                 [1.0, 2.0, 1.0], np.eye(3)),
                               [0.02, 0.005, 0.0], atol=1e-12)


def test_schedule_commands_what_the_open_loop_simulator_commands():
    scene = load_scene(ROOT / 'config' / 'scenes' / 'default.yaml')
    sched = TorqueSchedule.from_scene(scene)
    sim = simulate(scene)
    t_s = np.arange(sim.t_torque.size) / scene.torque_sensor.rate
    planned = np.array([sched.at(t) for t in t_s])
    np.testing.assert_allclose(planned, sim.torque_command, atol=1e-12)
    np.testing.assert_allclose(sched.at(sched.span + 1.0), sched.at(1.0), atol=1e-12)


# --------------------------------------------------------------------------------------------
# wheel speed limit
# --------------------------------------------------------------------------------------------

def _wheels(max_speed=100.0, inertia=1e-3):
    from inertia_ros.core.excitation.actuators import WheelLimit

    return [WheelLimit(f'rw{k + 1}', np.eye(3)[k], inertia, max_speed=max_speed)
            for k in range(3)]


def test_wheel_speed_check_refuses_speeding_up_past_the_limit_and_passes_braking():
    """A wheel along x at 99.5 of 100 rad/s, J = 1e-3: a body torque -0.02 N m about x
    spins it up by 20 rad/s^2 (0.6 rad/s in 0.03 s: over), +0.02 slows it (passes), and
    the same torque with 0.01 s to go stays under."""
    from inertia_ros.core.exciter_rules import wheel_speed_check

    w = _wheels()
    speeds = np.array([99.5, 0.0, 0.0])
    why = wheel_speed_check(speeds, np.array([-0.02, 0, 0]), w, 0.03)
    assert 'rw1' in why and '100' in why and 'max_speed' in why
    assert wheel_speed_check(speeds, np.array([0.02, 0, 0]), w, 0.03) == ''
    assert wheel_speed_check(speeds, np.array([-0.02, 0, 0]), w, 0.01) == ''
    assert wheel_speed_check(-speeds, np.array([0.02, 0, 0]), w, 0.03) != ''


def test_wheels_hold_zero_before_their_limit_and_resume_when_braking():
    """Closed loop on the wheel speeds (w += dt m / J with m = -tau): a planned -0.05 N m
    about x drives rw1 towards 100 rad/s; the rules hold zero before it crosses (the speed
    never exceeds 100 rad/s), say which wheel, and pass an opposite (braking) plan again.
    Without wheel speeds yet, they hold zero."""
    r = rules(max_slew=1.0)
    r.set_wheels(_wheels())
    cmd = run(r, [-0.05, 0, 0])
    assert cmd.state == 'holding' and 'no wheel speeds' in cmd.reason
    speeds, peak, states = np.zeros(3), 0.0, []
    for k in range(1, 200):
        t = k * DT
        r.on_gyro(t, np.zeros(3))
        r.on_wheel_speeds(t, speeds)
        cmd = r.step(t, np.array([-0.05, 0.0, 0.0]))
        speeds = speeds - DT * cmd.torque / 1e-3
        peak = max(peak, float(np.max(np.abs(speeds))))
        states.append((cmd.state, cmd.reason))
    assert peak <= 100.0
    assert peak >= 95.0
    assert states[-1][0] == 'holding' and 'wheel speed limit: rw1' in states[-1][1]
    assert np.all(cmd.torque == 0.0)
    r.on_wheel_speeds(200 * DT, speeds)
    r.on_gyro(200 * DT, np.zeros(3))
    cmd = r.step(200 * DT, np.array([0.05, 0.0, 0.0]))
    assert cmd.state == 'exciting' and cmd.torque[0] > 0


def test_stale_wheel_speeds_hold_zero_and_coplanar_wheels_are_refused():
    """Wheel speeds older than gyro_timeout hold zero; wheels that cannot produce torque
    about every axis are refused (ValueError naming the span)."""
    from inertia_ros.core.excitation.actuators import WheelLimit

    r = rules()
    r.set_wheels(_wheels())
    r.on_wheel_speeds(0.0, np.zeros(3))
    cmd = run(r, [0.01, 0, 0], t0=1.0)
    assert cmd.state == 'holding' and 'no wheel speeds for' in cmd.reason
    with pytest.raises(ValueError, match='span only 2'):
        r.set_wheels([WheelLimit('a', [1, 0, 0], 1e-3), WheelLimit('b', [0, 1, 0], 1e-3)])
