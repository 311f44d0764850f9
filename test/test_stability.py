"""Stability: no silent failure of the default method on a coarse grid; bench building blocks."""
from __future__ import annotations

import io

import numpy as np
import pytest

from inertia_ros.bench.methods import (
    DEFAULT_METHOD,
    hand_fd,
    method_specs,
    pinocchio_available,
    pinocchio_regressor,
)
from inertia_ros.bench.montecarlo import Bound, Run, pareto_front, summarize
from inertia_ros.bench.progress import Progress
from inertia_ros.bench.stability import SILENT_THRESHOLD, classify, grid_scene, run_grid
from inertia_ros.core.inertia import euler_torque, theta_to_matrix
from inertia_ros.core.simulation import simulate

# Coarse grid: gyro noise [rad/s] x multisine amplitude [N m], 20 s records.
NOISES = (3e-4, 3e-3, 3e-2)
AMPLITUDES = (0.003, 0.03, 0.3)


@pytest.mark.slow
def test_default_method_has_no_silent_failures() -> None:
    """On the coarse grid (3 seeds per cell) the default method is within 10 % or reports a
    failure status."""
    specs, _ = method_specs(include_pinocchio=False, quick=True)
    default = [s for s in specs if s.name == DEFAULT_METHOD]
    cells = run_grid(default, NOISES, AMPLITUDES, (20.0,), (1, 2, 3))
    assert len(cells) == len(NOISES) * len(AMPLITUDES) * 3
    silent = [(c.gyro_noise, c.amplitude, c.status, round(c.error, 3)) for c in cells
              if c.outcome == 'silent']
    assert silent == []
    # the grid is not trivially easy: the well-excited low-noise corner is accurate
    best = [c for c in cells if c.gyro_noise == NOISES[0] and c.amplitude == AMPLITUDES[-1]]
    assert all(c.outcome == 'ok' and c.error < 0.01 for c in best), best


@pytest.mark.parametrize(('status', 'error', 'expected'), [
    ('ok', 0.01, 'ok'),
    ('ok', SILENT_THRESHOLD, 'ok'),
    ('ok', 0.11, 'silent'),
    ('ok', float('nan'), 'silent'),
    ('insufficient_excitation', float('nan'), 'reported'),
    ('partially_identifiable', 0.5, 'reported'),
])
def test_classify(status: str, error: float, expected: str) -> None:
    """Cells are ok, reported (failure status) or silent (ok with error above 10 %)."""
    assert classify(status, error) == expected


def test_grid_scene_sets_the_three_axes() -> None:
    """grid_scene changes gyro noise, every torque amplitude and the duration (exact)."""
    sc = grid_scene(0.005, 0.2, 12.0)
    assert sc.gyro.noise_std == 0.005
    assert sc.duration == 12.0
    assert all(np.all(np.asarray(c.amplitude) == 0.2) for c in sc.torque)


@pytest.mark.parametrize(('kwargs', 'message'), [
    ({'gyro_noise': 0.0}, 'gyro_noise: must be a positive number'),
    ({'amplitude': -1.0}, 'amplitude: must be a positive number'),
    ({'duration': float('nan')}, 'duration: must be a positive number'),
])
def test_grid_scene_validation(kwargs: dict, message: str) -> None:
    """Non-positive grid values raise ValueError naming the argument."""
    args = {'gyro_noise': 1e-3, 'amplitude': 0.1, 'duration': 10.0} | kwargs
    with pytest.raises(ValueError, match=message):
        grid_scene(**args)


@pytest.mark.parametrize(('points', 'front'), [
    ([(1.0, 1.0), (2.0, 0.5), (3.0, 0.7), (0.5, 2.0)], [3, 0, 1]),
    ([(1.0, 1.0), (1.0, 1.0)], [0, 1]),
    ([(1.0, float('nan')), (2.0, 1.0)], [1]),
])
def test_pareto_front(points: list, front: list) -> None:
    """The Pareto front keeps exactly the non-dominated (time, error) points, by time."""
    assert pareto_front(points) == front


def test_summarize_efficiency() -> None:
    """Efficiency is trace(CRLB) / trace(MSE) over ok runs; failures do not count (rtol 1e-12)."""
    e1 = np.array([1.0, 0, 0, 0, 0, 0]) * 1e-3
    e2 = np.array([0, 2.0, 0, 0, 0, 0]) * 1e-3
    runs = [Run('s', 'm', 0, 'ok', 0.01, e1, 0.1), Run('s', 'm', 1, 'ok', 0.02, e2, 0.3),
            Run('s', 'm', 2, 'insufficient_data', float('nan'), np.full(6, np.nan), 0.2)]
    bound = Bound(theta_var=np.full(6, 1e-7), rel_frobenius=1e-3, spread=0.0,
                  nuisances=('wx0',))
    (s,) = summarize(runs, {'s': bound})
    assert (s.runs, s.ok, s.silent) == (3, 2, 0)
    mse = (e1 ** 2 + e2 ** 2) / 2
    np.testing.assert_allclose(s.mse, mse, rtol=1e-12, atol=0)
    np.testing.assert_allclose(s.efficiency, 6e-7 / mse.sum(), rtol=1e-12, atol=0)
    np.testing.assert_allclose(s.median_seconds, 0.2, rtol=1e-12, atol=0)


def test_hand_fd_exact_without_noise() -> None:
    """The by-hand baseline recovers the tensor from exact derivatives of a smooth motion."""
    I = theta_to_matrix(np.array([1.0, 1.2, 0.9, 0.05, -0.03, 0.02]))
    t = np.linspace(0.0, 10.0, 20001)
    omega = np.column_stack([0.3 * np.sin(0.7 * t), 0.2 * np.cos(1.1 * t), 0.25 * np.sin(
        1.9 * t + 0.3)])
    wd = np.column_stack([0.21 * np.cos(0.7 * t), -0.22 * np.sin(1.1 * t),
                          0.475 * np.cos(1.9 * t + 0.3)])
    tau = euler_torque(I, omega, wd)
    est = hand_fd(t, omega, t, tau)
    np.testing.assert_allclose(est, I, rtol=0, atol=1e-6)


def test_pinocchio_matches_hand_fd() -> None:
    """Pinocchio's body regressor gives the same least-squares tensor as hand_fd (rtol 1e-9)."""
    ok, info = pinocchio_available()
    if not ok:
        pytest.skip(f'pinocchio not importable: {info}')
    sim = simulate(grid_scene(1e-3, 0.1, 4.0), seed=3)
    a = hand_fd(sim.t_gyro, sim.omega, sim.t_torque, sim.torque)
    b = pinocchio_regressor(sim.t_gyro, sim.omega, sim.t_torque, sim.torque)
    np.testing.assert_allclose(b, a, rtol=1e-9, atol=1e-12)


def test_progress_draws_only_when_enabled() -> None:
    """The progress bar writes nothing to a non-TTY stream and a \\r line when forced on."""
    quiet = io.StringIO()
    p = Progress(3, stream=quiet)
    p('a')
    p.close()
    assert quiet.getvalue() == ''
    loud = io.StringIO()
    p = Progress(2, stream=loud, enabled=True)
    p('a')
    p('b')
    p.close()
    assert loud.getvalue().startswith('\r') and '2/2' in loud.getvalue()
    with pytest.raises(ValueError, match='total: must be >= 1'):
        Progress(0)


def test_bench_command_registered_and_checks_scenes(tmp_path, capsys) -> None:
    """`bench` is a CLI command; a scene directory without the scenes is a one-line error."""
    from inertia_ros.cli import build_parser, main

    args = build_parser().parse_args(['bench', '--quick', '--out', str(tmp_path)])
    assert args.quick and args.out == str(tmp_path)
    assert main(['bench', '--quick', '--scenes', str(tmp_path), '--out', str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and '--scenes' in err[0] and 'default.yaml' in err[0]
