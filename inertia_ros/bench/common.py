"""Helpers shared by the benchmark subcommands: the nominal scene at another size, timing."""
from __future__ import annotations

import os
import subprocess
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ['ROOT', 'SCENE_DIR', 'best_of', 'nominal_scene', 'process_env', 'relative_error',
           'timed_process']

#: This source tree (the directory holding the ``inertia_ros`` package).
ROOT = Path(__file__).resolve().parents[2]
#: The standard scenes of the source tree.
SCENE_DIR = ROOT / 'config' / 'scenes'


#: Sample budget of the benchmarks' own long scenes (a user's scene file gets 5e5).
BENCH_MAX_EVENTS = 5e7


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
    return Scene.from_dict(d, max_events=BENCH_MAX_EVENTS)


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


def process_env(blas_threads: int | None = None, pycache: str | None = None,
                tree: Path | str = ROOT) -> dict[str, str]:
    """The environment of a measured process: the source tree ``tree`` first on the path.

    With ``pycache`` (a directory) the process keeps its bytecode there, as an installed
    package has it (``PYTHONDONTWRITEBYTECODE`` would make every run compile the package's
    sources again, ~0.2 s; the source tree is never written).  ``blas_threads`` sets
    ``OPENBLAS/OMP/MKL_NUM_THREADS`` (default: inherited).
    """
    env = dict(os.environ)
    if pycache is not None:
        env.pop('PYTHONDONTWRITEBYTECODE', None)
        env['PYTHONPYCACHEPREFIX'] = pycache
    env['PYTHONPATH'] = os.pathsep.join(p for p in (str(tree), env.get('PYTHONPATH')) if p)
    if blas_threads is not None:
        for var in ('OPENBLAS_NUM_THREADS', 'OMP_NUM_THREADS', 'MKL_NUM_THREADS'):
            env[var] = str(blas_threads)
    return env


def timed_process(cmd: list[str], env: dict[str, str], cwd: str | None = None
                  ) -> tuple[float, str]:
    """Wall time [s] of one process from exec to exit, and its stdout; raises RuntimeError
    (with the last line of its stderr) when it fails."""
    t = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, check=False, env=env, cwd=cwd)
    dt = time.perf_counter() - t
    if proc.returncode != 0:
        raise RuntimeError(f'{" ".join(cmd[:4])}...: exit {proc.returncode}: '
                           f'{(proc.stderr.strip().splitlines() or [""])[-1]}')
    return dt, proc.stdout
