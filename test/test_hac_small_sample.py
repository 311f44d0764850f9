"""The filtered method's Newey-West covariance on short records (issue 27: sigma true on
short records too): the small-sample correction (:func:`.fit.hac_small_sample`)."""
from __future__ import annotations

import numpy as np
import pytest

from inertia_ros.bench.vibration_sim import wheel_throw
from inertia_ros.core.estimation.fit import hac_small_sample
from inertia_ros.core.estimation.momentum import Wheel, estimate_with_momentum, wheels_momentum

_IDX = [(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)]


def _z(seed: int) -> np.ndarray:
    """z of the six elements of a model-conforming 0.5 s wheel throw (white gyro noise only),
    ``filtered`` at a quarter of the wheel's lowest rotation frequency (about 5 filter
    periods: 90 kept equations for 12 parameters)."""
    r = wheel_throw(seed, duration=0.5, clean=True)
    mom = wheels_momentum(r.t_speed, r.speed, [Wheel('fly', r.wheel_axis, r.wheel_inertia)])
    e = estimate_with_momentum(r.t_gyro, r.omega, r.t_torque, r.torque, mom,
                               method='filtered', window=4.0 / r.line_hz, model='full')
    assert e.inertia is not None
    sd = np.sqrt(np.diag(np.asarray(e.covariance)))
    return np.array([(e.inertia[i][j] - r.inertia[i, j]) / sd[k]
                     for k, (i, j) in enumerate(_IDX)])


@pytest.mark.slow
def test_short_throw_sigma_is_true():
    """Over 12 seeds the RMS z is within [0.7, 1.25] (1.45 over 20 seeds without the
    correction: the plain Newey-West sigma is 1.5x small on 0.5 s; 0.97 with it)."""
    z = np.array([_z(s) for s in range(12)])
    rms = float(np.sqrt(np.mean(z ** 2)))
    assert 0.7 <= rms <= 1.25, rms


def test_white_errors_need_no_correction():
    """White errors over many equations: the factor is within 3 % of 1 (n = 400, lag 2, 6
    parameters); never below 1."""
    rng = np.random.default_rng(0)
    X = rng.normal(size=(400, 3, 6))
    e = rng.normal(size=(400, 3))
    shapes = np.zeros((2, 9))
    shapes[:, 0] = 1.0
    f = hac_small_sample(X, np.eye(3), e, 2, shapes)
    assert np.all(f >= 1.0) and np.all(f < 1.03), f


def test_correlated_errors_on_few_equations_are_corrected():
    """Errors correlated over the whole Bartlett lag on 60 equations (lag 8, 9 parameters): the
    plain estimate is biased low, and the factor says so (> 1.5 on every parameter)."""
    rng = np.random.default_rng(1)
    n, lag = 60, 8
    shape = np.clip(1.0 - np.arange(4 * lag + 1) / (2.0 * lag), 0.0, None)
    t = np.arange(n)[:, None, None]
    X = np.sin(0.05 * t * rng.uniform(0.5, 1.5, (1, 3, 9)) + rng.uniform(0, 6, (1, 3, 9)))
    e = np.convolve(rng.normal(size=n + 2 * lag), np.ones(2 * lag), 'valid')[:n, None] \
        * np.ones((1, 3))
    f = hac_small_sample(X, np.eye(3), e, lag, np.stack([shape, shape]))
    assert np.all(f > 1.5), f
