"""Stated input uncertainties that cover the error (issue 27): the status stays ``ok`` and the
sigma stays true.

Two seeded Monte Carlo runs through the batch momentum form with its defaults (the plain
``estimate LOG --wheels F`` / ``--rotors F`` path):

* wheels: a skewed pyramid of four reaction wheels (the project's scene simulator), each
  wheel's inertia off by a draw of its stated 0.5 % sigma;
* rotors: an independent RK4 quadrotor written here (body rates with rotor momentum, Imu and
  rotor speeds only), the rotors YAML's ``k_f``, ``k_m`` and ``J`` drawn within their stated
  1 / 2 / 3 % sigmas.

Acceptance (issue 27): ``model_mismatch`` in at most 1 of 10 records, RMS z in [0.7, 1.5], no
``ok`` with ``|z| > 5``, and the sigma with stated coefficients never smaller than with the
exact ones.
"""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from inertia_ros.core.estimation.momentum import Wheel, estimate_with_momentum, wheels_momentum
from inertia_ros.core.estimation.rotors import RotorSet, rotors_momentum
from inertia_ros.core.scene import Scene
from inertia_ros.core.simulation import simulate
from inertia_ros.io.rotors import load_rotors

ROOT = Path(__file__).resolve().parents[1]
IDX = ([0, 1, 2, 0, 0, 1], [0, 1, 2, 1, 2, 2])
RECORDS = 10


# ------------------------------------------------------------------------------ rotors
def _speeds(t: np.ndarray, hover: float, amp: np.ndarray, freq: np.ndarray,
            phase: np.ndarray, mix: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotor speeds (n, 4) [rad/s] and their time derivatives: hover plus a multisine on
    each of three mixing directions (roll, pitch, yaw), smooth for an exact derivative."""
    s = np.sin(2 * np.pi * freq[None] * t[:, None] + phase[None]) * amp[None]     # (n, 3)
    c = np.cos(2 * np.pi * freq[None] * t[:, None] + phase[None]) * amp[None]
    return hover + s @ mix, (2 * np.pi * freq[None] * c) @ mix


def rk4_quadrotor(rotors: RotorSet, inertia: np.ndarray, seed: int, duration: float = 8.0,
                  rate: float = 200.0, gyro_std: float = 0.002, speed_std: float = 1.0,
                  substeps: int = 8) -> dict:
    """An independent quadrotor: ``I w' = tau - w x (I w + h) - h'`` by RK4 at ``substeps``
    steps per sample, ``tau = sum w_i^2 (k_f p_i x a - s_i k_m a)``, ``h = sum J_i s_i w_i
    a`` (the true coefficients of ``rotors``); gyro and rotor speeds sampled at ``rate`` with
    white noise.  Returns the streams and the truth."""
    rng = np.random.default_rng(seed)
    a = rotors.axis
    P = np.array([r.position for r in rotors.rotors])
    s = np.array([r.spin for r in rotors.rotors], dtype=float)
    kf = np.array([r.k_f for r in rotors.rotors])
    km = np.array([r.k_m for r in rotors.rotors])
    J = np.array([r.inertia for r in rotors.rotors])
    rows = kf[:, None] * np.cross(P, a) - (s * km)[:, None] * a          # torque per w^2
    # mixing: speed changes that roll, pitch and yaw the body (least-squares inverse)
    mix = np.linalg.pinv(rows.T * 2 * 660.0)                              # (4, 3)
    mix = mix.T
    amp = np.array([0.06, 0.06, 0.02]) * (1 + 0.2 * rng.standard_normal(3))
    freq = np.array([0.53, 0.71, 0.37]) * (1 + 0.1 * rng.random(3))
    phase = rng.uniform(0, 2 * np.pi, 3)
    Ii = np.linalg.inv(inertia)

    def f(t: float, w: np.ndarray) -> np.ndarray:
        sp, dsp = _speeds(np.array([t]), 660.0, amp, freq, phase, mix)
        tau = (sp[0] ** 2) @ rows
        h = (J * s * sp[0]).sum() * a
        dh = (J * s * dsp[0]).sum() * a
        return Ii @ (tau - np.cross(w, inertia @ w + h) - dh)

    n = int(round(duration * rate)) + 1
    t = np.arange(n) / rate
    dt = 1.0 / rate / substeps
    w = np.zeros((n, 3))
    w[0] = rng.normal(0.0, 0.02, 3)
    x = w[0].copy()
    for k in range(1, n):
        for j in range(substeps):
            tk = t[k - 1] + j * dt
            k1 = f(tk, x)
            k2 = f(tk + dt / 2, x + dt / 2 * k1)
            k3 = f(tk + dt / 2, x + dt / 2 * k2)
            k4 = f(tk + dt, x + dt * k3)
            x = x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        w[k] = x
    sp = _speeds(t, 660.0, amp, freq, phase, mix)[0]
    return {'t': t, 'omega': w + rng.normal(0.0, gyro_std, w.shape),
            'speed': sp + rng.normal(0.0, speed_std, sp.shape), 'inertia': inertia}


def _drawn(stated: RotorSet, rng: np.random.Generator) -> RotorSet:
    """True coefficients: the stated ones off by a draw of their stated sigma."""
    return RotorSet(tuple(replace(r, k_f=r.k_f + r.k_f_std * rng.standard_normal(),
                                  k_m=r.k_m + r.k_m_std * rng.standard_normal(),
                                  inertia=r.inertia + r.inertia_std * rng.standard_normal())
                          for r in stated.rotors), stated.axis)


def _exact(rs: RotorSet) -> RotorSet:
    """The same coefficients without stated sigmas."""
    return RotorSet(tuple(replace(r, k_f_std=0.0, k_m_std=0.0, inertia_std=0.0)
                          for r in rs.rotors), rs.axis)


def _summary(zs: list, statuses: list, worst_ok: float) -> str:
    rms = float(np.sqrt(np.mean(np.square(zs))))
    return f'statuses {statuses}, RMS z {rms:.3g}, largest ok |z| {worst_ok:.3g}'


def _accept(zs: list, statuses: list, sig_ratio: list) -> None:
    """The issue's acceptance over the records."""
    zs = np.array(zs)
    ok = np.array([s == 'ok' for s in statuses])
    worst_ok = float(np.max(np.abs(zs[ok]))) if ok.any() else 0.0
    seen = _summary(list(zs), statuses, worst_ok) + f', sigma ratio min {min(sig_ratio):.3g}'
    rms = float(np.sqrt(np.mean(np.square(zs))))
    assert sum(s == 'model_mismatch' for s in statuses) <= len(statuses) // 10, seen
    assert 0.7 <= rms <= 1.5, seen
    assert worst_ok <= 5.0, seen
    assert min(sig_ratio) >= 1.0 - 1e-9, seen


@pytest.mark.slow
def test_rotors_off_within_their_stated_sigma() -> None:
    """Issue 27: an independent RK4 quadrotor, Imu + rotor speeds only, the rotors YAML's
    k_f, k_m, J drawn within their stated 1/2/3 %: ok in >= 9 of 10 logs, RMS z in [0.7,
    1.5], no ok at |z| > 5; the sigma never below the exact coefficients' one (on 5a72dae:
    5 of 10 model_mismatch, RMS z 2.0, one ok at |z| 9.8)."""
    stated = load_rotors(ROOT / 'bags' / 'quadrotor_rotors.yaml')
    truth = np.array([[0.015, 0.0004, -0.0002], [0.0004, 0.017, 0.0003],
                      [-0.0002, 0.0003, 0.028]])
    zs, statuses, ratio = [], [], []
    for seed in range(RECORDS):
        true = _drawn(stated, np.random.default_rng(500 + seed))
        rec = rk4_quadrotor(true, truth, seed)
        m = rotors_momentum(rec['t'], rec['speed'], stated)
        e = estimate_with_momentum(rec['t'], rec['omega'], [], np.zeros((0, 3)), m)
        x = estimate_with_momentum(rec['t'], rec['omega'], [], np.zeros((0, 3)),
                                   rotors_momentum(rec['t'], rec['speed'], _exact(true)))
        statuses.append(e.status)
        zs.append((e.theta - truth[IDX]) / e.theta_std)
        ratio.append(float(np.min(e.theta_std / x.theta_std)))
    _accept(zs, statuses, ratio)


# ------------------------------------------------------------------------------ wheels
def _pyramid_scene(duration: float) -> dict:
    """Four reaction wheels in a pyramid (54.7 deg from +z) skewed by 15 deg about +z."""
    el, skew = np.arccos(1 / np.sqrt(3)), np.radians(15.0)
    axes = [[np.sin(el) * np.cos(skew + k * np.pi / 2), np.sin(el) * np.sin(skew + k * np.pi / 2),
             np.cos(el)] for k in range(4)]
    speeds = [(40.0, 0.11, 0.0), (-30.0, 0.17, 1.0), (20.0, 0.23, 2.0), (-10.0, 0.29, 3.0)]
    return {'name': 'pyramid', 'duration': duration,
            'body': {'inertia': [0.12, 0.10, 0.08, 0.004, -0.003, 0.002]},
            'initial_omega': [0.05, -0.03, 0.02], 'torque': [],
            'gyro': {'rate': 100.0, 'noise_std': 2e-3},
            'wheels': {'rate': 100.0, 'speed_noise_std': 0.2, 'list': [
                {'joint': f'rw{k + 1}', 'axis': axes[k], 'inertia': 1.2e-3,
                 'speed': {'offset': o, 'amplitude': 150.0, 'frequency': f, 'phase': p}}
                for k, (o, f, p) in enumerate(speeds)]}}


@pytest.mark.slow
def test_pyramid_wheels_off_within_their_stated_sigma() -> None:
    """Issue 27: a skewed pyramid of four wheels, each inertia 0.5 % off (a draw of the stated
    0.5 % sigma): ok in >= 9 of 10, RMS z in [0.7, 1.5], no ok at |z| > 5; the sigma never
    below the exact inertias' one (on 5a72dae: 2 of 5 model_mismatch at RMS z 1.15)."""
    sc = Scene.from_dict(_pyramid_scene(8.0))
    zs, statuses, ratio = [], [], []
    for seed in range(RECORDS):
        r = simulate(sc, seed)
        rng = np.random.default_rng(900 + seed)
        used = [Wheel(w.joint, w.axis, w.inertia * (1 + 0.005 * rng.standard_normal()),
                      0.005 * w.inertia) for w in sc.wheels.wheels]
        e = estimate_with_momentum(r.t_gyro, r.omega, [], np.zeros((0, 3)),
                                   wheels_momentum(r.t_wheel, r.wheel_speed, used))
        exact = [Wheel(w.joint, w.axis, w.inertia) for w in sc.wheels.wheels]
        x = estimate_with_momentum(r.t_gyro, r.omega, [], np.zeros((0, 3)),
                                   wheels_momentum(r.t_wheel, r.wheel_speed, exact))
        statuses.append(e.status)
        zs.append((e.theta - r.inertia[IDX]) / e.theta_std)
        ratio.append(float(np.min(e.theta_std / x.theta_std)))
    _accept(zs, statuses, ratio)
