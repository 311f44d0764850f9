"""``method='auto'`` chooses the formulation and its band from the data (issue 27, item 1).

Realistic records come from :mod:`inertia_ros.bench.vibration_sim` (independent of the
project's simulator): a short flywheel throw and a torque-driven record whose gyro sees an
imbalance line at the rotation frequency and its harmonic, a structural mode, a band limit and
coloured noise, none of which the rigid-body model contains.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from inertia_ros.bench.vibration_sim import torque_record, wheel_throw
from inertia_ros.cli import main
from inertia_ros.core.estimation.batch import estimate
from inertia_ros.core.estimation.method_choice import (
    lowest_rotation_hz,
    residual_spectrum,
    spectral_evidence,
)
from inertia_ros.core.estimation.momentum import Wheel, estimate_with_momentum, wheels_momentum

SEEDS = range(10)


def _throw_run(r, **options):
    """The momentum-form estimate of a throw (its one wheel from its speed stream)."""
    mom = wheels_momentum(r.t_speed, r.speed, [Wheel('fly', r.wheel_axis, r.wheel_inertia)])
    return estimate_with_momentum(r.t_gyro, r.omega, r.t_torque, r.torque, mom, **options)


def _torque_run(r, **options):
    return estimate(r.t_gyro, r.omega, r.t_torque, r.torque, **options)


def _score(results, records):
    """Errors [%] (Frobenius, relative), |z| of the principal moments, statuses."""
    errs, zs, status = [], [], []
    for e, r in zip(results, records, strict=True):
        status.append(e.status)
        if e.inertia is None or e.principal_moments is None:
            errs.append(np.inf)
            zs += [np.inf] * 3
            continue
        errs.append(100 * np.linalg.norm(e.inertia - r.inertia) / np.linalg.norm(r.inertia))
        z = ((np.asarray(e.principal_moments) - np.linalg.eigvalsh(r.inertia))
             / np.asarray(e.diagnostics['principal_moments_std']))
        zs += list(np.abs(z))
    return np.array(errs), np.array(zs), status


def _check_auto(auto, hand, records):
    """The acceptance of the item: median error no worse than the best hand-set band, >= 90 %
    of principal moments within 3 sigma, no ok with error > 10 %, filtered chosen."""
    e_auto, z_auto, st = _score(auto, records)
    best_hand = min(float(np.median(_score(h, records)[0])) for h in hand)
    assert np.median(e_auto) <= best_hand, (np.median(e_auto), best_hand)
    assert np.mean(z_auto < 3.0) >= 0.9, np.mean(z_auto < 3.0)
    assert not any(s == 'ok' and e > 10.0 for s, e in zip(st, e_auto, strict=True))
    for e in auto:
        sel = e.diagnostics['method_selection']
        assert sel['chosen'] == 'filtered' and e.method == 'filtered'
        assert sel['evidence']['found'] and sel['evidence']['cutoff_hz'] > 0
        # (ml is no candidate where the integral stage kept a torque fixed in inertial axes:
        # its likelihood has none; on the motor-line records the misfit keeps one on some)
        assert set(sel['candidates']) >= {'integral', 'filtered'}


@pytest.mark.slow
def test_flywheel_throws_auto_beats_the_hand_set_band() -> None:
    """Ten 1.5 s flywheel throws: auto (the wheel's speeds giving the rotation line) against
    filtered at half the lowest rotation frequency, the expert's setting (measured: auto
    median 0.41 %, 100 % within 3 sigma, all ok; hand 0.72 %; ml 4.7 %, 30 %)."""
    records = [wheel_throw(s) for s in SEEDS]
    auto = [_throw_run(r, rotation_hz=lowest_rotation_hz(r.speed)) for r in records]
    hand = [[_throw_run(r, method='filtered', window=2.0 / r.line_hz) for r in records]]
    _check_auto(auto, hand, records)
    # the default formulation is what fails here: model_mismatch with a far too small sigma
    ml = [_throw_run(r, method='ml') for r in records]
    e_ml, z_ml, _ = _score(ml, records)
    assert np.median(e_ml) > 2 * np.median(_score(auto, records)[0])
    assert np.mean(z_ml < 3.0) < 0.9


@pytest.mark.slow
def test_torque_records_auto_from_the_spectrum_alone() -> None:
    """Ten 3 s torque-driven records with a motor line at 35 Hz, no speeds given: the band
    comes from the residual spectrum.  Auto against the best of three hand-set cutoffs (1/2,
    1/4, 1/6 of the line; measured: auto 1.5 %, the best hand 2.9 %, 1/2 of the line 32 %)."""
    records = [torque_record(s) for s in SEEDS]
    auto = [_torque_run(r) for r in records]
    hand = [[_torque_run(r, method='filtered', window=k / r.line_hz) for r in records]
            for k in (2.0, 4.0, 6.0)]
    _check_auto(auto, hand, records)


def test_clean_data_keep_todays_choice() -> None:
    """Model-conforming records (white gyro noise only): auto finds no evidence and returns
    exactly today's ml result, with or without a known rotation line."""
    r = wheel_throw(3, clean=True)
    auto = _throw_run(r, rotation_hz=lowest_rotation_hz(r.speed))
    ml = _throw_run(r, method='ml')
    sel = auto.diagnostics['method_selection']
    assert sel['chosen'] == 'ml' and not sel['evidence']['found'] and 'candidates' not in sel
    np.testing.assert_array_equal(auto.inertia, ml.inertia)
    np.testing.assert_array_equal(auto.inertia_std, ml.inertia_std)
    r = torque_record(3, clean=True)
    auto, ml = _torque_run(r), _torque_run(r, method='ml')
    assert auto.method == 'ml' and not auto.diagnostics['method_selection']['evidence']['found']
    np.testing.assert_array_equal(auto.inertia, ml.inertia)


def test_spectral_evidence_finds_lines_and_not_white_noise() -> None:
    """White residuals: no evidence in 50 of 50; the same with one line (amplitude 5x the
    noise std) at 40 Hz: found, the line within a bin of 40 Hz, the edge at or below it."""
    rng = np.random.default_rng(0)
    t = np.arange(0.0, 2.0, 1e-3)
    inertia = np.eye(3)
    found = 0
    for _ in range(50):
        w = 0.01 * rng.standard_normal((len(t), 3))
        f, p, seg = residual_spectrum(t, w, np.zeros(0), np.zeros((0, 3)), inertia, None, 'zoh')
        found += spectral_evidence(f, p, seg, 2.0)['found']
    assert found == 0
    w = 0.01 * rng.standard_normal((len(t), 3))
    w[:, 0] += 0.05 * np.sin(2 * np.pi * 40.0 * t)
    f, p, seg = residual_spectrum(t, w, np.zeros(0), np.zeros((0, 3)), inertia, None, 'zoh')
    ev = spectral_evidence(f, p, seg, 2.0)
    df = f[1] - f[0]
    assert ev['found'] and any(abs(x - 40.0) <= df for x in ev['lines_hz'])
    assert ev['edge_hz'] <= 40.0 + df


def test_long_record_spectrum_on_spread_segments(monkeypatch: pytest.MonkeyPatch) -> None:
    """A record of 1405 Welch segments (720 001 samples, torque held, a fitted bias): the
    spectrum averages 256 of them, evenly spread, each integrated from its own start; against
    all 1405 (the cap lifted) every bin within 20 % (median 4 %; measured 11 % and 2.3 %),
    the 40 Hz line in the same bin, and the same evidence: that line and band edge."""
    import inertia_ros.core.estimation.method_choice as mc

    rng = np.random.default_rng(3)
    t = np.arange(720_001) / 200.0
    w = 0.02 * rng.standard_normal((len(t), 3)) + 0.3 * np.sin(0.05 * t)[:, None]
    w[:, 1] += 0.05 * np.sin(2 * np.pi * 40.0 * t)
    ts = np.arange(0.0, t[-1] + 1e-9, 0.02)
    tau = 0.1 * np.sin(0.3 * ts)[:, None] * np.ones(3)
    inertia = np.diag([1.0, 1.2, 0.9])
    args = (t, w, ts, tau, inertia, [1e-3, -2e-3, 0.0], 'zoh')
    f, p, seg = residual_spectrum(*args)
    monkeypatch.setattr(mc, 'MAX_SEGMENTS', 10**9)
    f_all, p_all, seg_all = residual_spectrum(*args)
    assert (seg, seg_all) == (256, 1405)
    np.testing.assert_array_equal(f, f_all)
    ratio = p[1:] / p_all[1:]
    assert np.max(np.abs(ratio - 1)) < 0.2 and np.median(np.abs(ratio - 1)) < 0.04
    assert np.argmax(p[1:]) == np.argmax(p_all[1:])
    ev, ev_all = (spectral_evidence(*x, t[-1]) for x in ((f, p, seg), (f_all, p_all, seg_all)))
    assert ev['found'] and ev_all['found'] and ev['lines_hz'] == ev_all['lines_hz']
    assert ev['edge_hz'] == ev_all['edge_hz']


def test_lowest_rotation_hz() -> None:
    """The slowest spinning joint's low percentile [Hz]; a stopped joint has no line."""
    s = np.column_stack([np.linspace(100.0, 200.0, 101), np.zeros(101)])
    assert lowest_rotation_hz(s) == pytest.approx(102.0 / (2 * np.pi))
    assert lowest_rotation_hz(np.zeros((10, 2))) is None
    assert lowest_rotation_hz(-s[:, :1]) == pytest.approx(102.0 / (2 * np.pi))


def _write_throw_log(path: Path, r) -> None:
    """A gyro + JointState log of a throw (no torque topic), as a real recording."""
    from inertia_ros.io import cdr_encode
    from inertia_ros.io.joint_state import JOINT_STATE, encode_joint_state
    from inertia_ros.io.mcap_writer import McapWriter, seconds_to_ns

    tg = seconds_to_ns(r.t_gyro + 100.0, 10**18)
    tw = seconds_to_ns(r.t_speed + 100.0, 10**18)
    with McapWriter(path) as w:
        w.add_topic('/imu', cdr_encode.IMU)
        w.add_topic('/fly/state', JOINT_STATE)
        w.write_many('/imu', tg, cdr_encode.encode_imu(tg, r.omega, 'base_link'))
        w.write_many('/fly/state', tw, encode_joint_state(tw, ['fly'], r.speed))


def test_cli_reports_the_choice_and_its_evidence(tmp_path: Path,
                                                 capsys: pytest.CaptureFixture) -> None:
    """``estimate LOG --wheels F`` with defaults on a throw: filtered, the rotation line from
    the JointState speeds in the evidence, in the JSON and the text report."""
    r = wheel_throw(1)
    log = tmp_path / 'throw.mcap'
    _write_throw_log(log, r)
    wheels = tmp_path / 'fly.yaml'
    a = r.wheel_axis
    wheels.write_text(f'wheels:\n  - joint: fly\n    axis: [{a[0]}, {a[1]}, {a[2]}]\n'
                      f'    inertia: {r.wheel_inertia}\n')
    assert main(['estimate', str(log), '--wheels', str(wheels), '--format', 'json',
                 '--no-progress']) == 0
    rep = json.loads(capsys.readouterr().out)
    sel = rep['diagnostics']['method_selection']
    assert rep['method'] == 'filtered' and sel['chosen'] == 'filtered'
    assert sel['evidence']['rotation_hz'] == pytest.approx(r.line_hz, rel=0.05)
    assert sel['evidence']['cutoff_hz'] < sel['evidence']['edge_hz'] <= r.line_hz * 1.05
    assert sel['candidates']['integral']['failed']
    assert sel['candidates']['filtered']['failed'] == []
    err = np.linalg.norm(np.array(rep['inertia']) - r.inertia) / np.linalg.norm(r.inertia)
    assert rep['status'] == 'ok' and err < 0.03
    assert main(['estimate', str(log), '--wheels', str(wheels), '--no-progress']) == 0
    text = capsys.readouterr().out
    assert 'method auto: filtered; residual spectrum' in text
    assert 'rotation line' in text and 'filter cutoff' in text
    assert 'rule: fewest failed tests' in text


@pytest.mark.slow
def test_faults_are_not_taken_for_vibration() -> None:
    """The reference simulator's faults (gyro bias, payload change, a slow sinusoidal
    disturbance): no spectral evidence, so auto is today's choice bit for bit and the fault
    stays visible (never filtered away into an ok)."""
    from inertia_ros.bench.truth_sim import TruthCase, simulate_truth

    base = TruthCase()
    cases = (base.with_(gyro_bias=(0.01, -0.005, 0.008)),
             base.with_(t_change=base.duration / 2, change=0.05),
             base.with_(disturbance=(0.05, 0.03, 0.04), disturbance_kind='sine',
                        disturbance_period=10.0))
    for case in cases:
        for r in simulate_truth(case, range(2)):
            auto = estimate(r.t_gyro, r.omega, r.t_torque, r.torque)
            ml = estimate(r.t_gyro, r.omega, r.t_torque, r.torque, method='ml')
            assert not auto.diagnostics['method_selection']['evidence']['found']
            assert auto.method == ml.method and auto.status == ml.status
            np.testing.assert_array_equal(auto.inertia, ml.inertia)


def test_node_batch_window_auto_uses_the_same_choice() -> None:
    """The node's ``method: batch`` with ``batch_method: auto`` solves its window with the
    same choice: filtered below the motor line on a vibrating torque record."""
    from inertia_ros.core.estimation.windowed import BatchWindow

    r = torque_record(2)
    win = BatchWindow(10.0, method='auto', model='full', hold='zoh')
    win.add_gyro(r.t_gyro, r.omega)
    win.add_torque(r.t_torque, r.torque)
    e = win.estimate()
    assert e.method == 'filtered' and e.diagnostics['method_selection']['chosen'] == 'filtered'
    assert e.status == 'ok'
    assert np.linalg.norm(e.inertia - r.inertia) / np.linalg.norm(r.inertia) < 0.05


@pytest.mark.slow
def test_short_throws_no_ok_far_off() -> None:
    """Eight 0.5 s throws (the short end of a hand throw, about 15 rotation periods): auto is
    never ok with an error over 10 %, and where it is ok its median error is no worse than
    the hand-set filtered's where that is ok (measured: 1.3 % against 2.2 %)."""
    records = [wheel_throw(s, duration=0.5) for s in range(8)]
    auto = [_throw_run(r, rotation_hz=lowest_rotation_hz(r.speed)) for r in records]
    hand = [_throw_run(r, method='filtered', window=2.0 / r.line_hz) for r in records]
    e_auto, _, st_auto = _score(auto, records)
    e_hand, _, st_hand = _score(hand, records)
    assert not any(s == 'ok' and e > 10.0 for s, e in zip(st_auto, e_auto, strict=True))
    ok_auto = [e for s, e in zip(st_auto, e_auto, strict=True) if s == 'ok']
    ok_hand = [e for s, e in zip(st_hand, e_hand, strict=True) if s == 'ok']
    assert len(ok_auto) >= 5 and np.median(ok_auto) <= np.median(ok_hand)
