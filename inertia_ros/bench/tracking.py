"""``bench tracking``: following a changing body, the Kalman tracker against a forgetting RLS.

Two scenes of the independent reference simulator (:mod:`.truth_sim`, which shares no code with
the estimators), the nominal body (gyro 200 Hz, 2 mrad/s noise; torque 50 Hz, 5 mN m noise,
0.2 N m multisine), 120 s each:

``step``
    a payload of +20 % of the tensor attached at 60 s without impulse (angular momentum
    conserved, the rate jumps);
``drift``
    fuel use, -1 %/min of the whole tensor.  Convention: the propellant leaves with the
    velocity of the body point it leaves from (no jet damping), so it carries its own angular
    momentum away and the body obeys ``I(t) w_dot + w x (I(t) w) = tau``: the ``(dI/dt) w``
    term of ``d(I w)/dt`` is the momentum the propellant takes along.

Both estimators get the same memory, a time constant of ``memory`` seconds (default 10 s):

- :class:`~inertia_ros.core.estimation.tracking.TrackingEstimator` (``window=memory``), fed as
  the node feeds it (10 ms blocks) and read at 10 Hz;
- the **baseline**, :class:`ForgettingRLS` below: a plain exponentially forgetting recursive
  least squares on the integral-form equations over each 0.1 s interval
  (``I (w_b - w_a) + int_a^b w x (I w) dt = int_a^b tau dt``), updated at 10 Hz with
  ``lambda = exp(-0.1 / memory)`` (0.990 at 10 s), the textbook tracker.

Reported per scene: the RMS relative Frobenius error against the current true tensor over
``t >= 10 s`` (median and range over the seeds), the tracker's RMS z-score of the six elements
against the current truth with its own sigma, the changes its innovation test found, and the
cost of one update of each (median wall time [us]).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from inertia_ros.core.estimation.regressors import (
    cumulative_monomials,
    cumulative_torque,
    gyroscopic_matrix,
    momentum_matrix,
)
from inertia_ros.core.estimation.tracking import TrackingEstimator

from .truth_sim import TruthCase, TruthRecord, simulate_truth

__all__ = ['SCENES', 'ForgettingRLS', 'SceneResult', 'run', 'run_scene']

#: The scenes: name -> TruthCase (120 s, nominal body and sensors).
SCENES: dict[str, TruthCase] = {
    'step': TruthCase(duration=120.0, t_change=60.0, change=0.20),
    'drift': TruthCase(duration=120.0, drift_per_s=-0.01 / 60.0),
}
#: Read-out period of both estimators [s] and the node's poll period [s].
READ_PERIOD = 0.1
POLL_PERIOD = 0.01
#: Errors are measured from this time on [s] (both estimators have started).
SKIP = 10.0


class ForgettingRLS:
    """The baseline: exponentially forgetting RLS on 0.1 s integral-form equations.

    Parameters
    ----------
    lam : float
        Forgetting factor per update (0 < lam <= 1).
    """

    def __init__(self, lam: float) -> None:
        self.lam = lam
        self.theta = np.zeros(6)
        self.P = np.eye(6) * 1e3

    def update(self, dw: np.ndarray, dm: np.ndarray, dT: np.ndarray) -> None:
        """One equation ``L(dw) theta + Q(dm) theta = dT`` (3 rows)."""
        A = momentum_matrix(dw) + gyroscopic_matrix(dm)
        PA = self.P @ A.T
        K = PA @ np.linalg.inv(self.lam * np.eye(3) + A @ PA)
        self.theta = self.theta + K @ (dT - A @ self.theta)
        P = (self.P - K @ PA.T) / self.lam
        self.P = 0.5 * (P + P.T)


def _truth(case: TruthCase, t: float) -> np.ndarray:
    """The true theta (6,) at time ``t`` (the simulator's rule: scale factor of I0)."""
    f = 1.0 + case.drift_per_s * t
    if case.t_change is not None and t >= case.t_change:
        f += case.change
    I = case.inertia * f
    return np.array([I[0, 0], I[1, 1], I[2, 2], I[0, 1], I[0, 2], I[1, 2]])


def _rel(theta: np.ndarray, truth: np.ndarray) -> float:
    """Relative Frobenius error of the tensors of two theta vectors."""
    w = np.array([1, 1, 1, 2, 2, 2], dtype=float)         # off-diagonals count twice
    return float(np.sqrt(np.sum(w * (theta - truth) ** 2) / np.sum(w * truth ** 2)))


def run_rls(case: TruthCase, rec: TruthRecord, memory: float) -> tuple[float, float]:
    """The baseline on one record: (RMS relative error for t >= SKIP, median us/update)."""
    tg, w = rec.t_gyro, rec.omega
    M = cumulative_monomials(tg, w, end_correction=False)
    T = cumulative_torque(rec.t_torque, rec.torque, tg)
    step = int(round(READ_PERIOD * case.gyro_rate))
    rls = ForgettingRLS(math.exp(-READ_PERIOD / memory))
    errs, cost = [], []
    for b in range(step, len(tg), step):
        a = b - step
        t0 = time.perf_counter()
        rls.update(w[b] - w[a], M[b] - M[a], T[b] - T[a])
        cost.append(time.perf_counter() - t0)
        if tg[b] >= SKIP:
            errs.append(_rel(rls.theta, _truth(case, float(tg[b]))))
    return float(np.sqrt(np.mean(np.square(errs)))), 1e6 * float(np.median(cost))


def run_tracker(case: TruthCase, rec: TruthRecord, memory: float
                ) -> tuple[float, np.ndarray, int, float]:
    """The tracker fed as the node feeds it: (RMS relative error, z-scores (n, 6), changes
    found, median us per update)."""
    est = TrackingEstimator(window=memory)
    tg, tq = rec.t_gyro, rec.t_torque
    errs, zs, cost = [], [], []
    ig = iq = 0
    every = int(round(READ_PERIOD / POLL_PERIOD))
    for k in range(1, int(round(case.duration / POLL_PERIOD)) + 1):
        t_now = k * POLL_PERIOD
        jg = int(np.searchsorted(tg, t_now, side='right'))
        jq = int(np.searchsorted(tq, t_now, side='right'))
        before = est.updates
        t0 = time.perf_counter()
        if jq > iq:
            est.add_torque(tq[iq:jq], rec.torque[iq:jq])
        if jg > ig:
            est.add_gyro(tg[ig:jg], rec.omega[ig:jg])
        if est.updates > before:
            cost.append((time.perf_counter() - t0) / (est.updates - before))
        ig, iq = jg, jq
        if k % every == 0 and t_now >= SKIP:
            cur = est.current()
            if cur is None:
                continue
            truth = _truth(case, t_now)
            errs.append(_rel(cur[0], truth))
            zs.append((cur[0] - truth) / np.sqrt(np.diag(cur[1])))
    return (float(np.sqrt(np.mean(np.square(errs)))), np.array(zs), len(est.changes),
            1e6 * float(np.median(cost)))


@dataclass
class SceneResult:
    """One scene over the seeds (errors relative, RMS over ``t >= SKIP``)."""

    scene: str
    tracker: list[float]
    rls: list[float]
    rms_z: float
    changes: list[int]
    tracker_us: float
    rls_us: float


def run_scene(name: str, seeds: list[int] | range, memory: float = 10.0,
              case: TruthCase | None = None) -> SceneResult:
    """Both estimators on every seed of scene ``name`` (or ``case``)."""
    case = SCENES[name] if case is None else case
    recs = simulate_truth(case, seeds)
    tr, rl, zs, ch, tus, rus = [], [], [], [], [], []
    for rec in recs:
        e, z, c, us = run_tracker(case, rec, memory)
        tr.append(e)
        zs.append(z)
        ch.append(c)
        tus.append(us)
        e, us = run_rls(case, rec, memory)
        rl.append(e)
        rus.append(us)
    z_all = np.concatenate(zs)
    return SceneResult(name, tr, rl, float(np.sqrt(np.mean(z_all ** 2))), ch,
                       float(np.median(tus)), float(np.median(rus)))


def run(seeds: int = 10, memory: float = 10.0, out: Any = print) -> int:
    """Run both scenes and print the table; return the exit status (0)."""
    out(f'bench tracking: {seeds} seeds per scene, memory {memory:g} s (RLS lambda '
        f'{math.exp(-READ_PERIOD / memory):.4f} at {1 / READ_PERIOD:g} Hz), errors RMS over '
        f't >= {SKIP:g} s against the current true tensor')
    out('scene  tracker error (median, range)   RLS error (median, range)    '
        'tracker RMS z  changes found  us/update tracker, RLS')
    for name in SCENES:
        r = run_scene(name, range(seeds), memory)
        out(f'{name:<6} {100 * np.median(r.tracker):6.3f} % '
            f'[{100 * min(r.tracker):.3f}, {100 * max(r.tracker):.3f}]   '
            f'{100 * np.median(r.rls):6.3f} % [{100 * min(r.rls):.3f}, {100 * max(r.rls):.3f}]'
            f'   {r.rms_z:5.2f}        {int(np.median(r.changes))} (median)    '
            f'{r.tracker_us:6.0f}, {r.rls_us:4.0f}')
    return 0
