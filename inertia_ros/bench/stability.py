"""Stability map: each method's error over gyro noise x excitation amplitude x duration.

The base is the nominal scene (``config/scenes/default.yaml``: principal moments around
1 kg m^2 with products of inertia, three-axis multisine, torque noise 2 % of its RMS); the grid
changes the gyro white-noise std [rad/s], the multisine peak amplitude [N m] and the record
duration [s].  Every cell is classified:

``ok``
    status ``ok`` and relative Frobenius error at most ``SILENT_THRESHOLD``;
``reported``
    the method reported a failure status (anything but ``ok``);
``silent``
    status ``ok`` but error above ``SILENT_THRESHOLD``: a silent failure.
"""
from __future__ import annotations

import copy
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from inertia_ros.core.scene import Scene
from inertia_ros.core.simulation import simulate

from .methods import MethodSpec
from .montecarlo import relative_error

__all__ = ['NOMINAL', 'SILENT_THRESHOLD', 'Cell', 'classify', 'grid_scene', 'run_grid']

#: Relative Frobenius error above which an ``ok`` result is a silent failure.
SILENT_THRESHOLD = 0.10

#: The nominal scene as a dict (same values as config/scenes/default.yaml).
NOMINAL: Mapping[str, Any] = {
    'name': 'nominal', 'seed': 7, 'duration': 60.0,
    'body': {'inertia': [1.0, 1.2, 0.9, 0.05, -0.03, 0.02]},
    'initial_omega': [0.05, -0.03, 0.02],
    'torque': [{'type': 'multisine', 'amplitude': 0.1, 'axes': ['x', 'y', 'z'],
                'f_min': 0.02, 'f_max': 0.5, 'n_freq': 6, 'phases': 'schroeder'}],
    'disturbance': [0.0, 0.0, 0.0], 'command_rate': 50.0,
    'gyro': {'rate': 200.0, 'noise_std': 0.002},
    'torque_sensor': {'rate': 50.0, 'noise_rel': 0.02, 'noise_std': 0.0},
}


def grid_scene(gyro_noise: float, amplitude: float, duration: float,
               base: Mapping[str, Any] = NOMINAL) -> Scene:
    """The base scene with one grid cell's gyro noise, amplitude and duration.

    Parameters
    ----------
    gyro_noise : float
        Gyro white-noise std [rad/s], > 0.
    amplitude : float
        Peak torque per axis of every torque component [N m], > 0.
    duration : float
        Record length [s], > 0.
    base : mapping
        Scene dict to start from (default :data:`NOMINAL`).

    Returns
    -------
    Scene

    Raises
    ------
    ValueError
        A non-positive grid value (or a base dict the scene schema rejects).
    """
    for name, v in (('gyro_noise', gyro_noise), ('amplitude', amplitude),
                    ('duration', duration)):
        if not np.isfinite(v) or v <= 0:
            raise ValueError(f'{name}: must be a positive number, got {v!r}')
    d = copy.deepcopy(dict(base))
    d['duration'] = float(duration)
    d['gyro'] = dict(d.get('gyro', {}), noise_std=float(gyro_noise))
    d['torque'] = [dict(c, amplitude=float(amplitude)) for c in d['torque']]
    d['name'] = f'{d.get("name", "grid")}_n{gyro_noise:g}_a{amplitude:g}_d{duration:g}'
    return Scene.from_dict(d)


def classify(status: str, error: float, threshold: float = SILENT_THRESHOLD) -> str:
    """``'ok'``, ``'reported'`` (failure status) or ``'silent'`` (ok but error > threshold).

    A NaN error with status ok (an ``ok`` result without a complete tensor) is silent.
    """
    if status != 'ok':
        return 'reported'
    if not np.isfinite(error) or error > threshold:
        return 'silent'
    return 'ok'


@dataclass(frozen=True)
class Cell:
    """One method on one grid record.

    Attributes
    ----------
    method : str
    gyro_noise : float
        [rad/s]
    amplitude : float
        [N m]
    duration : float
        [s]
    seed : int
    status : str
    error : float
        Relative Frobenius error (NaN when no complete tensor).
    outcome : str
        :func:`classify` of the cell.
    reported_std : float
        The method's own relative standard error ``||I_std||_F / ||I||_F`` (NaN if none).
    """

    method: str
    gyro_noise: float
    amplitude: float
    duration: float
    seed: int
    status: str
    error: float
    outcome: str
    reported_std: float = float('nan')


def run_grid(specs: Sequence[MethodSpec], noises: Sequence[float], amplitudes: Sequence[float],
             durations: Sequence[float], seeds: Sequence[int],
             base: Mapping[str, Any] = NOMINAL,
             progress: Callable[[str], None] | None = None) -> list[Cell]:
    """Run every method on every grid record.

    Parameters
    ----------
    specs : sequence of MethodSpec
    noises : sequence of float
        Gyro noise std values [rad/s].
    amplitudes : sequence of float
        Torque peak amplitudes [N m].
    durations : sequence of float
        Record lengths [s].
    seeds : sequence of int
        Simulation seeds per cell.
    base : mapping
        Base scene dict.
    progress : callable, optional
        Called with a label after each estimate.

    Returns
    -------
    list of Cell
    """
    out: list[Cell] = []
    for dur in durations:
        for amp in amplitudes:
            for noise in noises:
                scene = grid_scene(noise, amp, dur, base)
                for seed in seeds:
                    sim = simulate(scene, seed=int(seed))
                    for spec in specs:
                        o = spec.run(sim)
                        err = relative_error(o.inertia, sim.inertia)
                        rstd = (float(np.linalg.norm(o.inertia_std) / np.linalg.norm(
                            sim.inertia)) if o.inertia_std is not None else float('nan'))
                        out.append(Cell(spec.name, float(noise), float(amp), float(dur),
                                        int(seed), o.status, err, classify(o.status, err),
                                        rstd))
                        if progress is not None:
                            progress(f'stability {spec.name}')
    return out
