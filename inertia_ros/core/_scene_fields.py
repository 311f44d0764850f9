"""Limits and small validators of scene dicts (each raises :class:`SceneError` naming the key).

Split from :mod:`inertia_ros.core.scene`, which re-exports them: the scene parsers of
:mod:`.wheel_sim` and :mod:`.rotor_sim` use them too.  The limits bound what a scene may ask
for, so a hostile scene file is refused in one line before anything large is allocated or a
long integration starts.
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from inertia_ros.core._validate import show

__all__ = ['MAX_ACTUATORS', 'MAX_ACTUATOR_SPEED', 'MAX_ACTUATOR_WORK', 'MAX_DROP_RATE',
           'MAX_DURATION', 'MAX_EVENTS', 'MAX_MAGNITUDE', 'MAX_NAME_CHARS', 'MAX_SUBSTEPS',
           'MAX_MULTISINE_TERMS', 'MAX_TORQUE_DELAY', 'SceneError', 'too_many_substeps']


class SceneError(ValueError):
    """A scene dict (or YAML file) that cannot be simulated; the message names the key."""


#: Largest number of samples (gyro + torque + command updates + JointState) a scene may ask
#: for: about 40 s and 2 GiB to simulate and write (1.8 h at 200 + 50 + 50 Hz).
MAX_EVENTS = 2e6
#: Most multisine terms (command samples x frequencies x axes), each a sine evaluation.
MAX_MULTISINE_TERMS = 20 * MAX_EVENTS
#: Most RK4 substeps of the rigid-body integrator (plain floats, 4-13 us each).
MAX_SUBSTEPS = 4e6
#: Most RK4 substeps times wheels (or rotors) with actuators: their numpy right-hand side
#: costs 0.1-0.4 ms per substep and joint (the shipped wheels and quadrotor scenes: 25k; the
#: budget allows about 20x their 60 s, a few minutes of integration).
MAX_ACTUATOR_WORK = 5e5
#: Fastest wheel or rotor [rad/s] (about 1 million rpm; real ones stay below 1e4).
MAX_ACTUATOR_SPEED = 1e5
#: Largest magnitude of any number in a scene (SI units).
MAX_MAGNITUDE = 1e12
#: Longest run [s] (11.6 days; stamps stay within the 32-bit seconds of a ROS time).
MAX_DURATION = 1e6
#: Largest torque-stream delay [s] (``imperfections.torque_delay``).
MAX_TORQUE_DELAY = 10.0
#: Largest ``imperfections.drop_rate``: beyond it a stream may keep no sample at all.
MAX_DROP_RATE = 0.9
#: Most wheels or rotors in a scene.
MAX_ACTUATORS = 64
#: Longest string of a scene (``name``, ``frame_id``, joints); ``description`` may be longer.
MAX_NAME_CHARS = 256


def too_many_substeps(t: float, rate: float, limit: float) -> SceneError:
    """The error of an integration that would need more than ``limit`` substeps.

    Parameters
    ----------
    t : float
        Simulated time reached [s].
    rate : float
        The body-rate bound there [rad/s] (may be inf).
    limit : float
        The substep budget.
    """
    return SceneError(f'the body turns too fast to simulate in bounded time: at t = {t:.3g} s '
                      f'its rate bound is {rate:.3g} rad/s, and the run needs more than '
                      f'{limit:.0e} integration steps; lower initial_omega, the torques or the '
                      'wheel speeds, or raise the inertia')


def _number(value: Any, key: str, *, positive: bool = False, nonneg: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise SceneError(f'{key}: must be a number, got {show(value)}')
    try:
        x = float(value)
    except OverflowError:               # a huge numpy or Python integer
        x = math.inf
    if not math.isfinite(x):
        raise SceneError(f'{key}: must be finite, got {show(value)}')
    if abs(x) > MAX_MAGNITUDE:
        raise SceneError(f'{key}: must be at most {MAX_MAGNITUDE:g} in magnitude, got '
                         f'{show(value)}')
    if positive and x <= 0.0:
        raise SceneError(f'{key}: must be a positive number, got {show(value)}')
    if nonneg and x < 0.0:
        raise SceneError(f'{key}: must be >= 0, got {show(value)}')
    return x


def _integer(value: Any, key: str, *, minimum: int = 0) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise SceneError(f'{key}: must be an integer, got {show(value)}')
    if int(value) < minimum:
        raise SceneError(f'{key}: must be >= {minimum}, got {show(value)}')
    if int(value) >= 2**63:
        raise SceneError(f'{key}: must be < 2^63, got {show(value)}')
    return int(value)


def _vector(value: Any, key: str, n: int = 3, *, nonneg: bool = False) -> np.ndarray:
    if isinstance(value, (str, bytes, Mapping)) or not isinstance(value, (Sequence, np.ndarray)):
        raise SceneError(f'{key}: must be a list of {n} numbers, got {show(value)}')
    if len(value) != n:
        raise SceneError(f'{key}: must be a list of {n} numbers, got {len(value)} items')
    out = np.array([_number(v, f'{key}[{i}]', nonneg=nonneg) for i, v in enumerate(value)])
    out.setflags(write=False)
    return out


def _vector_or_scalar(value: Any, key: str, *, nonneg: bool = False) -> np.ndarray:
    if isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool):
        x = _number(value, key, nonneg=nonneg)
        out = np.full(3, x)
        out.setflags(write=False)
        return out
    return _vector(value, key, nonneg=nonneg)


def _string(value: Any, key: str, choices: Sequence[str] | None = None,
            max_chars: int = MAX_NAME_CHARS) -> str:
    if not isinstance(value, str):
        raise SceneError(f'{key}: must be a string, got {show(value)}')
    if len(value) > max_chars:
        raise SceneError(f'{key}: at most {max_chars} characters, got {len(value)}')
    if choices is not None and value not in choices:
        raise SceneError(f'{key}: must be one of {", ".join(choices)}; got {show(value)}')
    return value


def _mapping(value: Any, key: str, known: Sequence[str]) -> Mapping[str, Any]:
    if value is None:
        return {}
    if not isinstance(value, Mapping):
        raise SceneError(f'{key}: must be a mapping, got {show(value)}')
    for k in value:
        if k not in known:
            raise SceneError(f'{key}.{str(k)[:40]}: unknown key (known: {", ".join(known)})')
    return value
