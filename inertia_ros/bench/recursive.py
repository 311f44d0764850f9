"""``bench recursive``: :class:`~inertia_ros.core.estimation.RecursiveEstimator` as the node
drives it.

The nominal scene simulated with gyro and torque both at ``rate`` Hz (default 1000) for
``duration`` s (default 60), as ``bench node`` sends it.  The estimator (the node's defaults:
model ``full``, no bias, no forgetting) is fed in 10 ms blocks (the node's poll period) and
``estimate()`` is called every 100 ms (publish rate 10 Hz).  Reported: median / p95 / max wall
time of ``estimate()`` over the second half of the record [ms], the feeding cost per gyro
sample [us] (``add_gyro`` + ``add_torque`` of the blocks, amortised processing included) and
the final estimate.  ``profile`` prints the top cProfile entries of the ``estimate()`` calls.
Timings depend on the machine's load.
"""
from __future__ import annotations

import cProfile
import pstats
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from inertia_ros.core.estimation import RecursiveEstimator
from inertia_ros.core.simulation import simulate

from .common import nominal_scene, relative_error

__all__ = ['POLL_PERIOD', 'PUBLISH_PERIOD', 'Timings', 'drive', 'run']

#: The node's poll period [s] and publish period [s].
POLL_PERIOD = 0.01
PUBLISH_PERIOD = 0.1


@dataclass
class Timings:
    """What :func:`drive` measured.

    Attributes
    ----------
    estimate_calls : list of (float, float)
        ``(record time [s], wall time of estimate() [s])`` per publish.
    feed_seconds : float
        Wall time of all add_gyro / add_torque calls [s].
    last : object
        The last estimate (an InertiaEstimate), or None.
    """

    estimate_calls: list[tuple[float, float]] = field(default_factory=list)
    feed_seconds: float = 0.0
    last: Any = None


def drive(sim: Any, duration: float, profiler: cProfile.Profile | None = None) -> Timings:
    """Feed ``sim`` in poll-period blocks and estimate at the publish rate.

    Parameters
    ----------
    sim : SimResult
        Streams to feed (times [s] from 0).
    duration : float
        Record length [s].
    profiler : cProfile.Profile, optional
        Enabled around each ``estimate()`` call.
    """
    tg, tq = sim.t_gyro, sim.t_torque
    rec = RecursiveEstimator(model='full')
    out = Timings()
    ig = iq = 0
    next_pub = PUBLISH_PERIOD
    for k in range(1, int(round(duration / POLL_PERIOD)) + 1):
        t_now = k * POLL_PERIOD
        jg = int(np.searchsorted(tg, t_now, side='right'))
        jq = int(np.searchsorted(tq, t_now, side='right'))
        t0 = time.perf_counter()
        if jg > ig:
            rec.add_gyro(tg[ig:jg], sim.omega[ig:jg])
        if jq > iq:
            rec.add_torque(tq[iq:jq], sim.torque[iq:jq])
        out.feed_seconds += time.perf_counter() - t0
        ig, iq = jg, jq
        if t_now >= next_pub - 1e-9:
            next_pub += PUBLISH_PERIOD
            if profiler is not None:
                profiler.enable()
            t0 = time.perf_counter()
            out.last = rec.estimate()
            out.estimate_calls.append((t_now, time.perf_counter() - t0))
            if profiler is not None:
                profiler.disable()
    return out


def run(rate: float = 1000.0, duration: float = 60.0, seed: int = 1,
        profile: bool = False) -> int:
    """Run the benchmark and print the figures; return the exit status (0).

    Parameters
    ----------
    rate : float
        Gyro and torque rate [Hz].
    duration : float
        Record length [s].
    seed : int
        Simulation seed.
    profile : bool
        Print the top cProfile entries of the ``estimate()`` calls.
    """
    sim = simulate(nominal_scene(duration, rate=rate), seed=seed)
    prof = cProfile.Profile() if profile else None
    t = drive(sim, duration, prof)
    late = np.array([dt for tn, dt in t.estimate_calls if tn >= 0.5 * duration]) * 1e3
    print(f'recursive, {len(sim.t_gyro)} gyro + {len(sim.t_torque)} torque samples at '
          f'{rate:g} Hz, {duration:g} s, 10 ms blocks, estimate() at 10 Hz')
    if late.size:
        print(f'estimate() second half: median {np.median(late):.3f} ms, '
              f'p95 {np.percentile(late, 95):.3f} ms, max {np.max(late):.3f} ms '
              f'({len(late)} calls)')
    print(f'feeding: {1e6 * t.feed_seconds / len(sim.t_gyro):.2f} us per gyro sample '
          '(with its torque sample)')
    if t.last is not None:
        print(f'final: status {t.last.status}, relative Frobenius error '
              f'{relative_error(t.last.inertia, sim.inertia):.3e}')
    if prof is not None:
        pstats.Stats(prof).sort_stats('cumulative').print_stats(25)
    return 0
