"""``bench startup``: wall time of the command line's start-up as whole processes.

Each case is run ``repeat`` times (default 5) as a fresh interpreter, after one untimed
warm-up run (file-system cache); the median and the range of the wall time are reported, and
the median CPU time (user + system), which a loaded machine disturbs less:

``estimate --help``
    ``python -m inertia_ros estimate --help`` (target < 0.3 s): argument parsing only, no
    numpy, scipy or matplotlib.
``--version``
    ``python -m inertia_ros --version``.
``import estimator node``
    ``python -c 'import inertia_ros.nodes.estimator'`` (target < 0.5 s; needs rclpy): the
    node class with rclpy and its messages (the ``inertia_estimator_node`` shim itself defers
    that import until the node runs).
``python -c pass``
    The interpreter alone, the floor under every figure.
"""
from __future__ import annotations

import resource
import statistics
import subprocess
import sys
import time
from dataclasses import dataclass

__all__ = ['CASES', 'StartupFigure', 'measure', 'run']

#: (name, interpreter arguments, target [s] or None).
CASES: tuple[tuple[str, tuple[str, ...], float | None], ...] = (
    ('estimate --help', ('-m', 'inertia_ros', 'estimate', '--help'), 0.3),
    ('--version', ('-m', 'inertia_ros', '--version'), None),
    ('import estimator node', ('-c', 'import inertia_ros.nodes.estimator'), 0.5),
    ('python -c pass', ('-c', 'pass'), None),
)


@dataclass(frozen=True)
class StartupFigure:
    """One case's timings.

    Attributes
    ----------
    name : str
    command : str
        The command as a user types it.
    seconds : tuple of float
        Wall time of each timed run [s].
    cpu_seconds : tuple of float
        User + system CPU time of each timed run [s] (less sensitive to the machine's load).
    target : float or None
        The target for the median [s].
    ok : bool
        Every run exited 0.
    """

    name: str
    command: str
    seconds: tuple[float, ...]
    target: float | None
    ok: bool
    cpu_seconds: tuple[float, ...] = ()

    @property
    def median(self) -> float:
        """Median wall time [s]."""
        return statistics.median(self.seconds)

    @property
    def median_cpu(self) -> float:
        """Median CPU time [s] (NaN when not measured)."""
        return statistics.median(self.cpu_seconds) if self.cpu_seconds else float('nan')

    @property
    def met(self) -> bool | None:
        """Whether the median meets the target (None without a target)."""
        return None if self.target is None else self.ok and self.median < self.target


def _time_once(argv: list[str]) -> tuple[float, float, bool]:
    """Wall time [s], CPU time [s] of one process and whether it exited 0."""
    c0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                          check=False)
    wall = time.perf_counter() - t0
    c1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (c1.ru_utime - c0.ru_utime) + (c1.ru_stime - c0.ru_stime)
    return wall, cpu, proc.returncode == 0


def measure(repeat: int = 5) -> list[StartupFigure]:
    """Time every case of :data:`CASES` ``repeat`` times (after one warm-up run)."""
    out = []
    for name, args, target in CASES:
        argv = [sys.executable, *args]
        _time_once(argv)
        runs = [_time_once(argv) for _ in range(max(1, repeat))]
        shown = 'python ' + ' '.join(a if ' ' not in a else repr(a) for a in args)
        out.append(StartupFigure(name, shown, tuple(r[0] for r in runs), target,
                                 all(r[2] for r in runs), tuple(r[1] for r in runs)))
    return out


def run(repeat: int = 5) -> int:
    """Print one line per case; return 0 when every target is met, 1 otherwise."""
    figures = measure(repeat)
    for f in figures:
        verdict = '' if f.target is None else (
            f'  target < {f.target:g} s: {"met" if f.met else "NOT met"}')
        failed = '' if f.ok else '  (a run exited non-zero)'
        print(f'{f.name:24s} median {f.median:.3f} s  (min {min(f.seconds):.3f}, max '
              f'{max(f.seconds):.3f}, {len(f.seconds)} runs; CPU {f.median_cpu:.3f} s)'
              f'{verdict}{failed}   [{f.command}]')
    return 0 if all(f.met is not False for f in figures) else 1
