"""Torque profiles of the planner: the designed multisine family and the standard profiles.

A profile is a list of scene torque components (``docs/SCENES.md``), so the simulator plays it.
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from .inputs import Limits, Prior, Profile, _theta

#: Fewest command samples per period of a multisine's highest frequency.
SAMPLES_PER_PERIOD = 5.0

__all__ = ['corner_frequency', 'design_candidates', 'multisine', 'scene_dict',
           'standard_profiles']


def standard_profiles(max_torque: Sequence[float]) -> list[Profile]:
    """The standard profiles at peak torque ``max_torque`` (3,) [N m] per axis.

    constant; sines (one per axis, 0.10 / 0.13 / 0.17 Hz); chirp (scene default: 0.02 to 1 Hz,
    one axis after the other); PRBS (0.5 s bits); random-phase multisine and Schroeder
    multisine (scene defaults: 6 tones per axis, 0.02 to 0.5 Hz).
    """
    mt = [float(v) for v in max_torque]
    sines = tuple({'type': 'sine', 'frequency': f, 'amplitude': mt, 'axes': [ax]}
                  for f, ax in zip((0.10, 0.13, 0.17), 'xyz', strict=True))
    return [Profile('constant', ({'type': 'constant', 'amplitude': mt},)),
            Profile('sines', sines),
            Profile('chirp', ({'type': 'chirp', 'amplitude': mt},)),
            Profile('prbs', ({'type': 'prbs', 'amplitude': mt, 'bit_time': 0.5},)),
            Profile('random multisine', ({'type': 'multisine', 'amplitude': mt,
                                          'phases': 'random'},)),
            Profile('schroeder multisine', ({'type': 'multisine', 'amplitude': mt},))]


def multisine(f0: float, n: int, decay: float, quadrature: bool,
              spread: float | None = None, stagger: bool = True) -> Profile:
    """A designed multisine as ``sine`` components (unit amplitude per tone).

    Parameters
    ----------
    f0 : float
        Base frequency [Hz].
    n : int
        Tones per axis.
    decay : float
        Tone amplitude ``h ** -decay`` for harmonic ``h`` (0 flat, 1 square-wave-like).
    quadrature : bool
        Turn the phases by 90 degrees (each tone a cosine: rate swings centred).
    spread : float, optional
        None: harmonic layout, axis ``j`` takes the harmonics ``h = 3 m + j + 1`` of ``f0``
        with Schroeder phases over all of them.  A number: axis ``j`` has its own base
        ``f0 (1 + spread j)`` and the odd harmonics ``h = 2 m + 1`` of it, the axes staggered
        by 120 degrees when ``stagger`` (else in phase).
    """
    comps = []
    for m in range(n):
        for j, ax in enumerate('xyz'):
            if spread is None:
                h = 3 * m + j + 1
                freq = h * f0
                phase = -math.pi * h * (h - 1) / (3 * n)
            else:
                h = 2 * m + 1
                freq = h * f0 * (1.0 + spread * j)
                phase = -math.pi * m * (m - 1) / n + (h * 2.0 * math.pi * j / 3.0
                                                      if stagger else 0.0)
            phase += math.pi / 2 if quadrature else 0.0
            amp = [0.0, 0.0, 0.0]
            amp[j] = float(h ** -decay)
            comps.append({'type': 'sine', 'frequency': float(freq), 'amplitude': amp,
                          'axes': [ax], 'phase': float(math.remainder(phase, 2 * math.pi))})
    layout = 'harmonic' if spread is None else f'spread {spread:g}'
    return Profile(f'designed multisine (f0 {f0:.4g} Hz, {n}/axis, {layout})', tuple(comps))


def _from(par: Mapping[str, Any]) -> Profile:
    """The multisine of a parameter dict (:func:`design_candidates`)."""
    return multisine(par['f0'], par['n_per_axis'], par['decay'], par['quadrature'],
                     par['spread'], par['stagger'])


def corner_frequency(prior: Prior, lim: Limits) -> float:
    """``f_c = u / (2 pi I omega_max)`` [Hz] (geometric mean over the axes): a full-torque tone
    below it would cross the body-rate limit."""
    u_over_i = np.asarray(lim.max_torque) / np.diag(prior.inertia)
    return float(np.exp(np.mean(np.log(u_over_i)))) / (2 * math.pi * lim.max_rate)


def design_candidates(prior: Prior, lim: Limits, horizon: float, rate: float
                      ) -> list[tuple[dict[str, Any], Profile]]:
    """The multisines searched by :func:`plan`: ``(parameters, profile)`` pairs.

    Base frequencies from ``f_c / 4`` to ``4 f_c`` (:func:`corner_frequency`), kept within one
    period per horizon and a highest tone at most ``rate / 5``; harmonic and spread layouts,
    one or a few tones per axis, flat or falling amplitudes, sine or cosine phases, axes
    staggered or in phase.
    """
    f_c = corner_frequency(prior, lim)
    out = []
    layouts = [(None, 1, 0.0, True), (None, 3, 0.0, True), (None, 3, 1.0, True),
               (0.15, 1, 0.0, True), (0.3, 1, 0.0, True), (0.15, 1, 0.0, False),
               (0.3, 1, 0.0, False), (0.15, 2, 1.0, True)]
    for spread, n, decay, stagger in layouts:
        top = 3 * n if spread is None else (2 * n - 1) * (1 + 2 * spread)
        hi, lo = rate / (SAMPLES_PER_PERIOD * top), 1.0 / horizon
        if hi < lo:
            continue
        for f0 in sorted({float(np.clip(f_c * k, lo, hi)) for k in (0.25, 0.5, 1.0, 2.0, 4.0)}):
            for quad in (False, True):
                par = {'f0': f0, 'n_per_axis': n, 'decay': decay, 'quadrature': quad,
                       'spread': spread, 'stagger': stagger}
                out.append((par, _from(par)))
    return out


def scene_dict(profile: Profile, lim: Limits, duration: float, inertia: np.ndarray,
               seed: int = 0, name: str = 'planned') -> dict[str, Any]:
    """A scene (``docs/SCENES.md`` schema) that plays ``profile`` on a body ``inertia``."""
    th = _theta(inertia)
    return {
        'name': name,
        'description': f'{profile.name}, planned by python -m inertia_ros plan',
        'seed': int(seed), 'duration': float(duration),
        'body': {'inertia': [float(v) for v in th]},
        'initial_omega': [float(v) for v in lim.initial_omega],
        'torque': [dict(c) for c in profile.components],
        'disturbance': [0.0, 0.0, 0.0],
        'command_rate': float(lim.torque_rate),
        'gyro': {'rate': float(lim.gyro_rate), 'noise_std': float(lim.gyro_noise),
                 'bias': [0.0, 0.0, 0.0], 'frame_id': 'base_link'},
        'torque_sensor': {'rate': float(lim.torque_rate), 'noise_rel': float(lim.torque_noise_rel),
                          'noise_std': float(lim.torque_noise)},
        'imperfections': {'timestamp_jitter': 0.0, 'torque_delay': 0.0, 'drop_rate': 0.0},
    }
