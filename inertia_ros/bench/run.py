"""The whole benchmark: Monte Carlo on the standard scenes, bounds, stability grid, outputs."""
from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from inertia_ros.core.estimation import to_jsonable
from inertia_ros.io.scene_file import load_scene

from .common import SCENE_DIR
from .methods import DEFAULT_METHOD, method_specs
from .montecarlo import as_records, run_monte_carlo, scene_bound, summarize
from .plots import plot_speed_vs_accuracy, plot_stability_map
from .progress import Progress
from .report import BenchContext, machine_info, render_markdown
from .stability import run_grid
from .startup import measure as measure_startup

__all__ = ['FULL', 'QUICK', 'SCENE_DIR', 'BenchConfig', 'run_bench']


@dataclass(frozen=True)
class BenchConfig:
    """Sizes of one benchmark run.

    Attributes
    ----------
    scenes : tuple of (name, file)
        Standard scenes (file names in ``config/scenes``).
    runs : dict of str to int
        Monte Carlo records per scene.
    bound_seeds : int
        Records the bound is first computed on; when it varies between them by more than 1 %
        (a random torque profile) it is averaged over every Monte Carlo record instead.
    noises, amplitudes, durations : tuple of float
        Stability grid: gyro noise [rad/s], torque amplitude [N m], duration [s].
    grid_seeds : tuple of int
        Seeds per grid cell.
    grid_methods : tuple of str
        Settings on the stability map.
    quick : bool
        Fewer settings.
    startup_repeat : int
        Runs per start-up case (median reported).
    """

    scenes: tuple[tuple[str, str], ...]
    runs: dict[str, int]
    bound_seeds: int
    noises: tuple[float, ...]
    amplitudes: tuple[float, ...]
    durations: tuple[float, ...]
    grid_seeds: tuple[int, ...]
    grid_methods: tuple[str, ...]
    quick: bool
    startup_repeat: int = 5


_GRID_METHODS = ('ml', 'integral', 'integral_ls', 'integral_sliding/1s', 'differential_fd',
                 'differential_sg/0.1s', 'recursive')

FULL = BenchConfig(
    scenes=(('nominal', 'default.yaml'), ('satellite', 'satellite.yaml'),
            ('cubesat', 'cubesat.yaml'), ('disturbance', 'disturbance.yaml'),
            ('chirp_steps', 'chirp_steps.yaml')),
    runs={'nominal': 30, 'satellite': 10, 'cubesat': 10, 'disturbance': 10,
          'chirp_steps': 10},
    bound_seeds=2,
    noises=(3e-4, 1e-3, 3e-3, 1e-2, 3e-2),
    amplitudes=(0.003, 0.01, 0.03, 0.1, 0.3),
    durations=(20.0, 60.0),
    grid_seeds=(1, 2, 3),
    grid_methods=_GRID_METHODS,
    quick=False)

QUICK = BenchConfig(
    scenes=(('nominal', 'default.yaml'), ('satellite', 'satellite.yaml')),
    runs={'nominal': 4, 'satellite': 3},
    bound_seeds=1,
    noises=(1e-3, 1e-2),
    amplitudes=(0.01, 0.1),
    durations=(20.0,),
    grid_seeds=(1,),
    grid_methods=_GRID_METHODS,
    quick=True,
    startup_repeat=3)


def _bounds(scenes: dict[str, Any], config: BenchConfig, n_records: dict[str, int],
            bar: Progress) -> dict[str, Any]:
    """The Cramer-Rao bound of each scene (averaged over every record when it varies)."""
    bounds = {}
    for name, sc in scenes.items():
        b = scene_bound(sc, [1000 + i for i in range(config.bound_seeds)])
        if b.spread > 0.01:
            # a random torque profile: the bound of every Monte Carlo record, averaged
            b = scene_bound(sc, [1000 + i for i in range(n_records[name])])
        bounds[name] = b
        bar(f'bound {name}')
    return bounds


def _timed(seconds: dict[str, float], key: str, fn: Any, *args: Any, **kw: Any) -> Any:
    """Call ``fn(*args, **kw)``, adding its wall time to ``seconds[key]`` [s]."""
    t0 = time.perf_counter()
    out = fn(*args, **kw)
    seconds[key] = seconds.get(key, 0.0) + time.perf_counter() - t0
    return out


def _headline(summaries: list[Any], cells: list[Any],
              seconds: dict[str, float]) -> dict[str, Any]:
    """The headline figures of bench_results.json."""
    by = {(s.scene, s.method): s for s in summaries}
    d = by.get(('nominal', DEFAULT_METHOD))
    return {
        'default_mse_over_crlb_nominal': (1.0 / d.efficiency) if d is not None else None,
        'default_efficiency_nominal': d.efficiency if d is not None else None,
        'default_median_error_nominal': d.median_error if d is not None else None,
        'default_silent_failures_on_grid': sum(1 for c in cells if c.method == DEFAULT_METHOD
                                               and c.outcome == 'silent'),
        'seconds': seconds,
    }


#: Sections other benchmarks write into BENCHMARKS.md start at this marker (for example
#: ``<!-- fleet-bench: ... -->`` of :mod:`inertia_ros.bench.fleet`): kept across reruns.
FOREIGN_MARKER = '\n<!-- '


def _kept_sections(doc: Path) -> str:
    """The part of an existing BENCHMARKS.md that other benchmarks wrote (from the first
    ``<!-- ...`` marker line to the end), to append after the regenerated text."""
    try:
        old = doc.read_text(encoding='utf-8')
    except OSError:
        return ''
    i = old.find(FOREIGN_MARKER)
    return old[i:] if i >= 0 else ''


def run_bench(out: Path, config: BenchConfig = FULL, scene_dir: Path = SCENE_DIR,
              show_progress: bool | None = None) -> dict[str, Any]:
    """Run the benchmark and write the charts, BENCHMARKS.md and bench_results.json.

    Parameters
    ----------
    out : Path
        Output directory (created when missing).
    config : BenchConfig
        :data:`FULL` or :data:`QUICK` (or your own).
    scene_dir : Path
        Where the scene files are.
    show_progress : bool, optional
        Draw a progress bar on stderr (default: when stderr is a terminal).

    Returns
    -------
    dict
        Headline figures (also in ``bench_results.json``).
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    t_start, cpu_start = time.perf_counter(), time.process_time()
    machine = machine_info()
    specs, notes = method_specs(quick=config.quick)
    scenes = {name: load_scene(scene_dir / f) for name, f in config.scenes}
    grid_specs = [s for s in specs if s.name in config.grid_methods]
    n_records = {name: config.runs[name] for name in scenes}
    n_grid = (len(config.noises) * len(config.amplitudes) * len(config.durations)
              * len(config.grid_seeds) * len(grid_specs))
    bar = Progress(sum(n_records.values()) * len(specs) + len(scenes) + n_grid,
                   enabled=show_progress)
    seconds: dict[str, float] = {}
    bounds = _timed(seconds, 'bounds', _bounds, scenes, config, n_records, bar)
    runs = _timed(seconds, 'monte_carlo', run_monte_carlo, scenes, specs, n_records,
                  base_seed=1000, progress=bar)
    summaries = summarize(runs, bounds)
    cells = _timed(seconds, 'stability', run_grid, grid_specs, config.noises,
                   config.amplitudes, config.durations, config.grid_seeds, progress=bar)
    bar.close()
    startup = _timed(seconds, 'startup', measure_startup, config.startup_repeat)
    _timed(seconds, 'plots', plot_speed_vs_accuracy, summaries, specs, bounds,
           out / 'speed_vs_accuracy.png')
    _timed(seconds, 'plots', plot_stability_map, cells, out / 'stability_map.png')
    grid = {'noises': list(config.noises), 'amplitudes': list(config.amplitudes),
            'durations': list(config.durations), 'seeds': list(config.grid_seeds),
            'records': {name: f'{sc.duration:g} s, gyro {sc.gyro.rate:g} Hz, torque '
                              f'{sc.torque_sensor.rate:g} Hz' for name, sc in scenes.items()}}
    seconds['total'] = time.perf_counter() - t_start
    seconds['cpu'] = time.process_time() - cpu_start
    ctx = BenchContext(quick=config.quick, scenes=dict(config.scenes), runs=n_records,
                       specs=specs, notes=notes, bounds=bounds, summaries=summaries,
                       cells=cells, grid=grid, machine=machine, seconds=seconds,
                       startup=startup)
    doc = out / 'BENCHMARKS.md'
    doc.write_text(render_markdown(ctx) + _kept_sections(doc), encoding='utf-8')
    headline = _headline(summaries, cells, seconds)
    payload = {'headline': headline, 'machine': machine, 'notes': notes,
               'bounds': {k: {'theta_var': b.theta_var, 'rel_frobenius': b.rel_frobenius,
                              'spread': b.spread, 'nuisances': list(b.nuisances)}
                          for k, b in bounds.items()},
               'summaries': as_records(summaries),
               'stability': [c.__dict__ for c in cells],
               'startup': [{'name': f.name, 'command': f.command, 'seconds': list(f.seconds),
                            'median': f.median, 'target': f.target} for f in startup],
               'config': {'quick': config.quick, 'runs': n_records, 'grid': grid}}
    (out / 'bench_results.json').write_text(
        json.dumps(to_jsonable(payload), indent=1), encoding='utf-8')
    ratio = headline['default_mse_over_crlb_nominal']
    return to_jsonable(headline) | {'default_mse_over_crlb_nominal_raw': float(ratio)
                                    if ratio is not None and np.isfinite(ratio) else None}
