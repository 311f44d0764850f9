"""Re-planning from the live estimate (issue 28, active identification).

While the exciter commands a planned profile, the estimator's tensor and covariance improve.
Every ``period`` seconds the exciter designs the next stretch of excitation again, with the
current estimate as the prior (value and covariance) and the current body rate as the initial
rate, so that the profile follows the body actually being excited (its corner frequency and
the torque the body-rate limit allows) rather than the prior it started from.

The criterion of a re-plan counts what is already known: the information of the next
``horizon`` seconds of a candidate is added to the information of the data so far (the inverse
of the estimate's covariance, on the model's elements), and the candidate with the smallest
largest targeted relative sigma at the end of the horizon wins.  The running profile is kept
unless a candidate is predicted better by ``min_gain`` (a switch costs a slew-limited jump).

Everything here is pure (no ROS); :class:`Replanner` is the exciter's bookkeeping: when a
re-plan is due, what the last one decided, and the figures it reports on /diagnostics.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ..simulation import integrate_rigid_body
from ..tensor import matrix_to_theta
from .design import (
    _DIAG_KEEP,
    DESIGN_RATE_MAX,
    _actuator_scales,
    _grid,
    enforce_limits,
    information_at,
    peak_rate,
    targeted_rel_std,
    theta_covariance,
)
from .inputs import Limits, Prior, Profile, Target, make_prior
from .profiles import _from, corner_frequency

__all__ = ['Continuation', 'Replan', 'ReplanSettings', 'Replanner', 'design_next',
           'predict_omega', 'prior_from_estimate', 'schedule_torque', 'with_wheel_speeds']

#: Samples per period of the highest tone a re-plan may place (at the given rate).
_SAMPLES_PER_PERIOD = 5.0

#: Base frequencies tried, as multiples of the estimate's corner frequency.
F0_FACTORS = (0.5, 0.71, 1.0, 1.41, 2.0)
#: Layouts tried: (spread, tones per axis, decay, stagger) as in :func:`.profiles.multisine`.
LAYOUTS = ((None, 1, 0.0, True), (0.15, 1, 0.0, True), (0.3, 1, 0.0, False))
#: Shortest lead [s] between the start of a re-plan and the start of its profile.
MIN_LEAD = 0.5
#: Largest share of ``max_rate`` taken as the initial rate of a re-plan.
OMEGA0_SHARE = 0.9
#: Largest share of a wheel's ``max_speed`` taken as its initial speed in a re-plan.
WHEEL_SPEED_SHARE = 0.99


@dataclass(frozen=True)
class ReplanSettings:
    """When and how the exciter re-plans.

    Attributes
    ----------
    period : float
        Seconds between re-plans [s], > 0.
    horizon : float
        Length of each re-planned profile [s], > 0 (it repeats after that until the next).
    min_gain : float
        Switch profile only when the new one's predicted criterion is lower by this fraction,
        in [0, 1).
    """

    period: float = 5.0
    horizon: float = 10.0
    min_gain: float = 0.1

    def __post_init__(self) -> None:
        for name in ('period', 'horizon'):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError(f'replan {name} must be a positive number, got {value!r}')
        if not (isinstance(self.min_gain, (int, float)) and 0.0 <= self.min_gain < 1.0):
            raise ValueError(f'replan min_gain must be in [0, 1), got {self.min_gain!r}')


@dataclass(frozen=True, eq=False)
class Replan:
    """The outcome of one re-plan.

    Attributes
    ----------
    profile : Profile or None
        The profile to command from now on (within the limits for the estimate), or None to
        keep the running one.
    design : dict
        The chosen multisine's parameters (:func:`.profiles.multisine`); ``{}`` when kept.
    criterion : float
        Predicted largest targeted relative sigma after ``horizon`` s of the chosen (or kept)
        profile, past data included [dimensionless].
    now : float
        Largest targeted relative sigma of the estimate itself [dimensionless].
    reason : str
        One line: what was decided and why.
    """

    profile: Profile | None
    design: dict[str, Any]
    criterion: float
    now: float
    reason: str


def prior_from_estimate(inertia: np.ndarray, cov: np.ndarray) -> Prior:
    """The estimate as a prior: value ``inertia`` (3, 3) [kg m^2] and the one-sigma of each
    element from ``cov`` (6, 6) [kg^2 m^4] (elements the estimate does not fit, zero variance,
    keep zero).

    Raises
    ------
    ValueError
        One line: a covariance that is not finite or not 6x6, a tensor that is not physical.
    """
    cov = np.asarray(cov, dtype=float)
    if cov.shape != (6, 6) or not np.all(np.isfinite(cov)):
        raise ValueError('estimate covariance: expected a finite 6x6 matrix')
    theta = matrix_to_theta(np.asarray(inertia, dtype=float), check_finite=False)
    return make_prior(theta, std=np.sqrt(np.clip(np.diag(cov), 0.0, None)))


def with_wheel_speeds(lim: Limits, speeds: Any) -> Limits:
    """``lim`` with each wheel's initial speed set to its measured speed ``speeds`` (n,)
    [rad/s] (in the order of ``lim.wheels``; a speed at or beyond ``WHEEL_SPEED_SHARE`` of
    ``max_speed`` is taken at that share, keeping its sign), so that a design keeps every
    wheel within its speed limit from where it is now.  ``lim`` itself when it has no wheels
    or ``speeds`` is None.

    Raises
    ------
    ValueError
        One line: not one finite speed per wheel.
    """
    if not lim.wheels or speeds is None:
        return lim
    w = np.asarray(speeds, dtype=float).reshape(-1)
    if w.size != len(lim.wheels) or not np.all(np.isfinite(w)):
        raise ValueError(f'wheel speeds: expected {len(lim.wheels)} finite values, got '
                         f'{w.tolist()}')
    wheels = tuple(replace(wl, initial_speed=float(np.clip(
        v, -WHEEL_SPEED_SHARE * wl.max_speed, WHEEL_SPEED_SHARE * wl.max_speed)))
        for wl, v in zip(lim.wheels, w, strict=True))
    return replace(lim, wheels=wheels)


def _past_information(cov: np.ndarray, model: str) -> np.ndarray:
    """Information (9, 9) on ``[theta, w0]`` of the data so far: the inverse of ``cov`` on the
    model's fitted elements with a positive variance (zero elsewhere)."""
    out = np.zeros((9, 9))
    fitted = _DIAG_KEEP[:3] if model == 'diagonal' else np.arange(6)
    idx = np.array([i for i in fitted if cov[i, i] > 0.0], dtype=int)
    if idx.size:
        block = cov[np.ix_(idx, idx)]
        out[np.ix_(idx, idx)] = np.linalg.pinv(0.5 * (block + block.T), hermitian=True)
    return out


def _criterion(info: np.ndarray, inertia: np.ndarray, target: Target, model: str) -> float:
    cov = theta_covariance(info, model)
    return max(targeted_rel_std(cov, inertia, target.elements).values())


def _candidates(prior: Prior, lim: Limits, horizon: float, rate: float,
                current: dict[str, Any] | None) -> list[dict[str, Any]]:
    """Parameter sets tried: :data:`LAYOUTS` at :data:`F0_FACTORS` of the corner frequency
    (sine and cosine phases), and the running design."""
    f_c = corner_frequency(prior, lim)
    out = [dict(current)] if current else []
    for spread, n, decay, stagger in LAYOUTS:
        top = 3 * n if spread is None else (2 * n - 1) * (1 + 2 * spread)
        hi, lo = rate / (_SAMPLES_PER_PERIOD * top), 1.0 / horizon
        if hi < lo:
            continue
        for f0 in sorted({float(np.clip(f_c * k, lo, hi)) for k in F0_FACTORS}):
            for quad in (False, True):
                out.append({'f0': f0, 'n_per_axis': n, 'decay': decay, 'quadrature': quad,
                            'spread': spread, 'stagger': stagger})
    return out


def design_next(inertia: np.ndarray, cov: np.ndarray, omega: np.ndarray, lim: Limits,
                target: Target, model: str, settings: ReplanSettings,
                current: dict[str, Any] | None = None, seed: int = 0,
                running: Any = None, keep_rate: float | None = None,
                wheel_speeds: Any = None) -> Replan:
    """Design the next ``settings.horizon`` seconds from the current estimate.

    Parameters
    ----------
    inertia : numpy.ndarray, shape (3, 3)
        Current estimate [kg m^2] (the new prior's value and the body the design is for).
    cov : numpy.ndarray, shape (6, 6)
        Its covariance [kg^2 m^4] (the information of the data so far).
    omega : numpy.ndarray, shape (3,)
        Body rate now [rad/s] (the design's initial rate, at most ``OMEGA0_SHARE max_rate``).
    lim : Limits
        Torque, body-rate, wheel and sensor figures (``initial_omega`` becomes ``omega``).
    target : Target
        Targeted quantities (``elements``); the criterion is their largest relative sigma.
    model : str
        ``full`` or ``diagonal`` (the estimator's).
    settings : ReplanSettings
        Horizon and switching gain.
    current : dict, optional
        Parameters of the running design: it is a candidate too, and the new design must beat
        it by ``settings.min_gain`` to replace it.
    seed : int
        Seed of the profile draws.
    running : object, optional
        The running profile's continuation from now: ``running.torque(t, duration, seed)``
        gives the torque (M, 3) [N m] it will command at ``t`` (M,) [s] from now.  It is
        scored as it is (not rescaled) and is the profile to beat; when its simulated body
        rate from ``omega`` would exceed ``keep_rate`` it cannot be kept.  Without it, the
        running design is ``current`` limited anew.
    keep_rate : float, optional
        Body rate [rad/s] the running profile may reach (default ``lim.max_rate``).
    wheel_speeds : array_like (n,), optional
        The wheels' speeds now [rad/s]: every design keeps the wheels within their limits
        from there (:func:`with_wheel_speeds`), and so must the running profile to be kept.

    Returns
    -------
    Replan

    Raises
    ------
    ValueError
        One line: an estimate that cannot be a prior (:func:`prior_from_estimate`).
    """
    prior = prior_from_estimate(inertia, cov)
    w = np.asarray(omega, dtype=float).reshape(3)
    speed = float(np.linalg.norm(w))
    if not math.isfinite(speed):
        raise ValueError(f'body rate: expected 3 finite numbers, got {w.tolist()}')
    if speed > OMEGA0_SHARE * lim.max_rate:
        w = w * (OMEGA0_SHARE * lim.max_rate / speed)
    lim = replace(with_wheel_speeds(lim, wheel_speeds),
                  initial_omega=tuple(float(v) for v in w))
    rate = min(DESIGN_RATE_MAX, lim.gyro_rate, lim.torque_rate)
    past = _past_information(np.asarray(cov, dtype=float), model)
    now = max(targeted_rel_std(np.asarray(cov, dtype=float), prior.inertia,
                               target.elements).values())
    h = settings.horizon
    scored = []
    for i, par in enumerate(_candidates(prior, lim, h, rate, current)):
        prof, _ = enforce_limits(_from(par), [prior.inertia], lim, h, rate, seed)
        F = information_at(prof, prior.inertia, lim, h, [h], rate, seed)[0]
        scored.append((_criterion(F + past, prior.inertia, target, model), i, par, prof))
    best = min(scored, key=lambda s: (s[0], s[1]))
    kept, why = _keep_score(running, prior, lim, target, model, h, rate, seed, past,
                            lim.max_rate if keep_rate is None else keep_rate)
    if running is None and current:
        kept, why = scored[0][0], ''
    if math.isfinite(kept) and not best[0] < (1.0 - settings.min_gain) * kept:
        return Replan(None, {}, kept, now, f'kept the running profile (predicted '
                      f'{100 * kept:.3g} % in {h:g} s; best new {100 * best[0]:.3g} %)')
    par = best[2]
    return Replan(best[3], dict(par), best[0], now,
                  f"new profile f0 {par['f0']:.3g} Hz, {par['n_per_axis']}/axis: predicted "
                  f'{100 * best[0]:.3g} % in {h:g} s (now {100 * now:.3g} %){why}')


def _keep_score(running: Any, prior: Prior, lim: Limits, target: Target, model: str,
                h: float, rate: float, seed: int, past: np.ndarray, keep_rate: float
                ) -> tuple[float, str]:
    """The running continuation's predicted criterion after ``h`` s (inf when there is none
    or it would cross ``keep_rate``) and a note for the reason line."""
    if running is None:
        return math.inf, ''
    pk = peak_rate(running, [prior.inertia], lim, h, lim.torque_rate, seed)
    F = information_at(running, prior.inertia, lim, h, [h], rate, seed)[0]
    crit = _criterion(F + past, prior.inertia, target, model)
    if lim.wheels or lim.rotors is not None:
        t = _grid(h, lim.torque_rate)
        share = float(np.min(_actuator_scales(t, running.torque(t, h, seed), lim)))
        if share < 1.0 - 1e-9:
            return math.inf, (f'; the running one would take a wheel or rotor '
                              f'{1.0 / max(share, 1e-12):.3g} x past its limit')
    if pk > keep_rate:
        return math.inf, (f'; the running one would reach {pk:.3g} rad/s on the estimate '
                          f'(> {keep_rate:.3g})')
    return crit, f'; the running one {100 * crit:.3g} %'


class Continuation:
    """A running torque schedule from a point on: ``torque(t, duration, seed)`` (the
    :class:`Profile` call) gives ``at(offset + t_i)`` for each ``t_i``.

    Parameters
    ----------
    at : callable
        ``at(t)`` -> torque (3,) [N m] of the running schedule at its time ``t`` [s].
    offset : float
        Schedule time [s] of "now".
    """

    def __init__(self, at: Any, offset: float) -> None:
        self._at, self.offset = at, float(offset)

    def torque(self, t: np.ndarray, duration: float = 0.0, seed: int = 0) -> np.ndarray:
        """Torque (M, 3) [N m] at ``t`` (M,) [s] from now (``duration``, ``seed`` unused)."""
        return np.array([self._at(self.offset + float(x)) for x in np.asarray(t)]
                        ).reshape(-1, 3)


def predict_omega(running: Any, inertia: np.ndarray, omega: np.ndarray, lead: float,
                  rate: float) -> np.ndarray:
    """Body rate (3,) [rad/s] ``lead`` s from now under the running continuation
    (:class:`Continuation`) from ``omega`` (3,) [rad/s], on the tensor ``inertia`` (3, 3)
    [kg m^2], torque held at ``rate`` [Hz]."""
    t = _grid(lead, rate)
    if t[-1] < lead - 1e-9:
        t = np.append(t, lead)
    if t.size < 2:
        return np.asarray(omega, dtype=float).copy()
    w, _ = integrate_rigid_body(t, running.torque(t[:-1]), inertia,
                                np.asarray(omega, dtype=float))
    return w[-1]


def schedule_torque(profile: Profile, duration: float, command_rate: float, seed: int = 0
                    ) -> tuple[np.ndarray, np.ndarray]:
    """``profile`` on the command grid: times (J,) [s] from 0 and torque (J, 3) [N m]."""
    t = _grid(duration, command_rate)[:-1]
    return t, profile.torque(t, duration, seed)


@dataclass
class Replanner:
    """The exciter's re-planning bookkeeping (pure; times in seconds on one clock).

    Parameters
    ----------
    settings : ReplanSettings
        Period, horizon, switching gain.
    design : dict, optional
        Parameters of the profile running at the start (None: a profile not from the
        multisine family; the first re-plan then always replaces it if it can).
    """

    settings: ReplanSettings
    design: dict[str, Any] | None = None
    t_last: float | None = None
    busy: bool = False
    replans: int = 0
    switches: int = 0
    last_reason: str = ''
    predicted: float = math.nan
    failures: int = 0
    late: int = 0
    lead: float = 1.0
    t_swap: float = math.inf
    history: list[tuple[float, str]] = field(default_factory=list)

    def due(self, t: float, t_start: float | None, have_estimate: bool, stopped: bool) -> bool:
        """True when a re-plan should start at ``t``: excitation running for at least one
        period since its start or the last re-plan, an estimate at hand, none in progress."""
        if stopped or self.busy or not have_estimate or t_start is None:
            return False
        since = t_start if self.t_last is None else self.t_last
        return t - since >= self.settings.period

    def started(self, t: float) -> float:
        """A re-plan started at ``t`` [s]; returns the time [s] at which its profile is to
        start (``t + lead``: the design starts from the rate predicted for then)."""
        self.busy, self.t_last = True, float(t)
        self.t_swap = float(t) + self.lead
        return self.t_swap

    def finished(self, t: float, outcome: Replan | None, error: str = '') -> bool:
        """A re-plan ended at ``t`` with ``outcome`` (or failed with ``error``); True when the
        running profile is to be replaced by ``outcome.profile`` at :attr:`t_swap` (False
        when the re-plan ended after that: it came from a rate that is gone).  The lead of
        the next re-plan is 1.5 times this one's computing time (at least ``MIN_LEAD``)."""
        self.busy = False
        self.replans += 1
        took = float(t) - (self.t_last if self.t_last is not None else float(t))
        late = float(t) > self.t_swap
        self.lead = min(max(MIN_LEAD, 1.5 * took), self.settings.period)
        if outcome is not None and outcome.profile is not None and late:
            self.late += 1
            self.last_reason = (f'late: took {took:.3g} s, past its start (lead now '
                                f'{self.lead:.3g} s)')
            self.history.append((float(t), self.last_reason))
            return False
        if outcome is None:
            self.failures += 1
            self.last_reason = f're-plan failed: {error}'
            self.history.append((float(t), self.last_reason))
            return False
        self.predicted = outcome.criterion
        self.last_reason = outcome.reason
        self.history.append((float(t), outcome.reason))
        if outcome.profile is None:
            return False
        self.design = dict(outcome.design)
        self.switches += 1
        return True

    def values(self) -> dict[str, str]:
        """Key/values for /diagnostics."""
        return {'replans': str(self.replans), 'replan_switches': str(self.switches),
                'replan_failures': str(self.failures), 'replan_late': str(self.late),
                'replan_predicted_rel_sigma': f'{self.predicted:.6g}',
                'replan_last': self.last_reason}
