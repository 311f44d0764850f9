"""Helpers shared by the benchmark subcommands: the nominal scene at another size, timing."""
from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ['SCENE_DIR', 'best_of', 'nominal_scene', 'relative_error']

#: The standard scenes of the source tree.
SCENE_DIR = Path(__file__).resolve().parents[2] / 'config' / 'scenes'


def nominal_scene(duration: float, rate: float | None = None) -> Any:
    """The nominal scene (``config/scenes/default.yaml``) with another duration or rate.

    Parameters
    ----------
    duration : float
        Record length [s].
    rate : float, optional
        When given, both the gyro and the torque sensor run at this rate [Hz].

    Returns
    -------
    inertia_ros.core.scene.Scene
    """
    from inertia_ros.core.scene import Scene
    from inertia_ros.io.scene_file import load_scene_dict

    d = load_scene_dict(SCENE_DIR / 'default.yaml')
    d['duration'] = duration
    if rate is not None:
        d['gyro'] = dict(d.get('gyro', {}), rate=rate)
        d['torque_sensor'] = dict(d.get('torque_sensor', {}), rate=rate)
    return Scene.from_dict(d)


def best_of(fn: Callable[[], Any], repeat: int = 3) -> tuple[float, Any]:
    """Best wall-clock time of ``repeat`` calls [s] and the last result.

    The minimum is the figure least disturbed by other processes (load only adds time).
    """
    import time

    best, out = np.inf, None
    for _ in range(max(1, repeat)):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return float(best), out


def relative_error(estimate: np.ndarray | None, truth: np.ndarray) -> float:
    """Relative Frobenius error ``||I_hat - I||_F / ||I||_F`` (NaN without an estimate)."""
    if estimate is None:
        return float('nan')
    return float(np.linalg.norm(np.asarray(estimate) - truth) / np.linalg.norm(truth))
