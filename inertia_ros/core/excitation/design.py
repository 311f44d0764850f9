"""Excitation design: which torque profile to command, and for how long.

From a prior tensor (value and uncertainty), the actuator and body-rate limits, the sensor rates
and noise, and a target precision, :func:`plan` designs a multisine torque profile that reaches
the target in as little time as it can, predicts the standard error of each tensor element and
principal moment against time (the Cramer-Rao bound of :mod:`.crlb`, which the project's ML
estimator attains), and compares the design with standard profiles at the same limits.

Profiles are lists of scene torque components (``docs/SCENES.md``): the designed multisine is a
sum of ``sine`` components, so a scene built from it is played exactly by the simulator.  Every
profile, designed or standard, is held to the same limits the same way: its peak torque per
axis is scaled to the limit, then the whole profile is scaled down until the simulated body
rate ``|omega|`` stays within the body-rate limit on every prior body.

Design
------
Per axis, ``n`` tones on harmonics of a base frequency ``f0`` (axis ``j`` takes the harmonics
``3 m + j + 1``, so the three axes never share a frequency), amplitudes flat or falling as
``1 / h`` (a square-wave-like spectrum that spends the torque on large rate swings), and
Schroeder phases (low crest factor) or the same phases turned by 90 degrees (rate swings
centred on the initial rate).  The base frequency is searched around the corner frequency
``u_max / (2 pi I omega_max)`` at which a full-amplitude tone just reaches the rate limit.
Each candidate is scored by its criterion (the largest targeted relative sigma) at the design
horizon, on the prior value and then, for the best few, on bodies drawn from the prior: the
worst case decides.  The standard profiles (:func:`.profiles.standard_profiles`, at the same
limits) then compete with the best designed candidates by time to target on further bodies
drawn from the prior (:func:`_robust_pick`): the plan is the designed multisine only when it is
sooner than every standard profile on every one of them, else a standard profile.

Information is evaluated at a reduced rate ``r`` with the noise rescaled to the same density
(gyro std ``sigma_g sqrt(r / rate_g)``, torque ``sigma_t sqrt(r / rate_t)``): the bound is
unchanged to < 2 % (``test/test_excitation.py``) at ``r / rate`` of the cost.

Model no more than the target needs: when the target asks only for the principal moments and
the prior's products of inertia are small (``|I_ij| <= NEAR_DIAGONAL sqrt(I_ii I_jj)``, and the
principal moments differ from the diagonal elements by at most a quarter of the target), the
information of the diagonal model (no product columns) is used and the estimator should be run
with ``model='diagonal'``; otherwise the full model's.  (Larger products bias a diagonal fit
and show in its residuals: the estimator would report a model mismatch.)
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.optimize import minimize_scalar

from ..crlb import cumulative_information
from ..simulation import integrate_rigid_body
from ..tensor import THETA_NAMES
from .actuators import (
    allocation,
    wheel_speed_scale,
    wheel_speeds,
    wheel_torque_scale,
    wheel_torques,
)
from .inputs import Limits, Prior, Profile, Target
from .profiles import (
    _from,
    corner_frequency,
    design_candidates,
    multisine,
    scene_dict,
    standard_profiles,
)

__all__ = ['Plan', 'binding_limits', 'choose_model', 'criterion', 'enforce_limits',
           'information_at', 'limit_usage', 'plan', 'principal_std', 'simulated_peak_rate',
           'targeted_rel_std', 'theta_covariance', 'time_to_reach', 'actuator_axis_scale']

#: Share of the body-rate limit a profile may use (margin for the prior's spread).
RATE_MARGIN = 0.97
#: Highest rate [Hz] at which information is evaluated during the design.
DESIGN_RATE_MAX = 10.0
#: Longest design horizon [s].
HORIZON_MAX = 60.0
#: Bodies drawn from the prior on which the plan's profile is checked (:func:`_robust_pick`).
N_CHECK = 16
#: How much sooner a designed multisine must be than every standard profile on every check
#: body to be planned.
DOMINANCE_MARGIN = 0.02
#: Standard profiles timed on the check bodies: within this factor of the best time to target
#: on the prior value.
CHECK_SHARE = 1.5
_DIAG_KEEP = np.array([0, 1, 2, 6, 7, 8])

# --------------------------------------------------------------------------------------------
# limits and information
# --------------------------------------------------------------------------------------------

def _grid(duration: float, rate: float) -> np.ndarray:
    """Sample times ``k / rate`` within ``[0, duration]`` [s]."""
    return np.arange(int(math.floor(duration * rate + 1e-9)) + 1) / rate


def peak_rate(profile: Profile, bodies: Sequence[np.ndarray], lim: Limits, duration: float,
              rate: float, seed: int = 0) -> float:
    """Largest noise-free ``|omega|`` [rad/s] over the bodies, torque held at ``rate`` [Hz]."""
    t = _grid(duration, rate)
    cmd = profile.torque(t, duration, seed)
    worst = 0.0
    for body in bodies:
        w, _ = integrate_rigid_body(t, cmd[:-1], body, np.asarray(lim.initial_omega))
        worst = max(worst, float(np.max(np.linalg.norm(w, axis=1))))
    return worst


def enforce_limits(profile: Profile, bodies: Sequence[np.ndarray], lim: Limits,
                   duration: float, rate: float, seed: int = 0) -> tuple[Profile, float]:
    """Scale ``profile`` to the torque limit per axis, then down to the body-rate limit.

    With wheels or rotors, the axes are then scaled down until every wheel's motor torque
    and speed (every rotor's speed) stay within its limits (:func:`actuator_axis_scale`).

    Returns
    -------
    profile : Profile
        Peak torque per axis ``<= max_torque`` on the command grid, wheel torques and
        speeds within their limits; noise-free peak body rate
        ``<= RATE_MARGIN max_rate`` on every body (torque held at the torque rate; ``rate``
        is ignored).
    peak : float
        That peak body rate [rad/s].
    """
    t = _grid(duration, lim.torque_rate)
    cmd = profile.torque(t, duration, seed)
    peak_u = np.max(np.abs(cmd), axis=0)
    f = np.where(peak_u > 0, np.asarray(lim.max_torque) / np.where(peak_u > 0, peak_u, 1), 0)
    if lim.wheels or lim.rotors is not None:
        f = f * actuator_axis_scale(t, cmd * f, lim)
    scaled = profile.scaled(f)
    w0 = float(np.linalg.norm(lim.initial_omega))
    allowed = RATE_MARGIN * lim.max_rate
    s = 1.0
    rate = lim.torque_rate          # the command as the actuator holds it
    pk = peak_rate(scaled, bodies, lim, duration, rate, seed)
    for _ in range(8):
        if pk <= allowed:
            break
        s *= 0.98 * (allowed - w0) / max(pk - w0, 1e-12)
        pk = peak_rate(scaled.scaled(s), bodies, lim, duration, rate, seed)
    return scaled.scaled(s), pk


def _actuator_scales(t: np.ndarray, tau: np.ndarray, lim: Limits) -> np.ndarray:
    """Per actuator (wheel or rotor) the largest factor ``<= 1`` for ``tau`` (M, 3)."""
    if lim.rotors is not None:
        return lim.rotors.speed_scale(tau)
    return np.minimum(wheel_torque_scale(lim.wheels, tau), wheel_speed_scale(lim.wheels, t, tau))


def actuator_axis_scale(t: np.ndarray, cmd: np.ndarray, lim: Limits) -> np.ndarray:
    """Per-axis factors ``<= 1``, (3,), that keep every wheel's motor torque and speed (or
    every rotor's speed) within its limits under the command ``cmd`` (M, 3) [N m] held on
    the grid ``t`` (M,) [s].

    An actuator over a limit scales down the axes it takes part in (allocation
    ``P_ki != 0``) by its own factor; a few rounds settle it (exact in one for wheels along
    the body axes), and a common factor closes any remainder (every limit is linear in the
    torque's scale).
    """
    P = lim.rotors.alloc[:, 1:] if lim.rotors is not None else allocation(lim.wheels)
    involved = np.abs(P) > 1e-9 * np.max(np.abs(P))              # (n, 3)
    f = np.ones(3)
    for _ in range(6):
        s = _actuator_scales(t, cmd * f, lim)
        if np.all(s >= 1.0 - 1e-9):
            return f
        f = f * np.min(np.where(involved, s[:, None], 1.0), axis=0)
    return f * float(min(1.0, np.min(_actuator_scales(t, cmd * f, lim))))


def limit_usage(profile: Profile, bodies: Sequence[np.ndarray], lim: Limits, duration: float,
                seed: int = 0) -> dict[str, float]:
    """Share of each limit the profile uses over ``duration`` [s] (1 = at the limit; the
    span it was sized for): ``axis torque`` (largest peak torque / max_torque over the
    axes), ``body rate`` (noise-free peak ``|omega|`` over ``bodies``, torque held at the
    torque rate, / max_rate) and per wheel ``wheel torque JOINT`` and ``wheel speed JOINT``
    (largest ``|w|`` / max_speed; unlimited ones are left out), per rotor ``rotor speed
    JOINT`` (largest share of its room from hover to a speed limit)."""
    t = _grid(duration, lim.torque_rate)
    cmd = profile.torque(t, duration, seed)
    out = {'axis torque': float(np.max(np.max(np.abs(cmd), axis=0)
                                        / np.asarray(lim.max_torque))),
           'body rate': peak_rate(profile, bodies, lim, duration, lim.torque_rate, seed)
           / lim.max_rate}
    if lim.wheels:
        m = np.max(np.abs(wheel_torques(lim.wheels, cmd)), axis=0)
        w = np.max(np.abs(wheel_speeds(lim.wheels, t, cmd)), axis=0)
        for k, wl in enumerate(lim.wheels):
            if math.isfinite(wl.max_torque):
                out[f'wheel torque {wl.joint}'] = float(m[k] / wl.max_torque)
            if math.isfinite(wl.max_speed):
                out[f'wheel speed {wl.joint}'] = float(w[k] / wl.max_speed)
    if lim.rotors is not None:
        share = lim.rotors.speed_share(cmd)
        out.update({f'rotor speed {j}': float(share[k])
                    for k, j in enumerate(lim.rotors.joints)})
    return out


def binding_limits(usage: dict[str, float], share: float = 0.98) -> str:
    """The limits within ``share`` of the largest use, most used first (comma-separated)."""
    top = max(usage.values())
    return ', '.join(k for k, v in sorted(usage.items(), key=lambda kv: -kv[1])
                     if v >= share * top)


def information_at(profile: Profile, body: np.ndarray, lim: Limits, duration: float,
             times: Sequence[float], rate: float, seed: int = 0) -> list[np.ndarray]:
    """Fisher information [theta, w0] of the record up to each of ``times`` [s].

    Evaluated at ``rate`` [Hz] (at most the sensor rates) with the noise rescaled to the same
    spectral density (module docstring).
    """
    t_cmd = _grid(duration, lim.torque_rate)
    cmd = profile.torque(t_cmd, duration, seed)
    rms = np.sqrt(np.mean(cmd ** 2, axis=0))
    t_std = lim.torque_noise + lim.torque_noise_rel * rms
    rg, rt = min(rate, lim.gyro_rate), min(rate, lim.torque_rate)
    ts = _grid(duration, rt)
    cmd_s = cmd[np.minimum(np.floor(ts * lim.torque_rate + 1e-6).astype(int), cmd.shape[0] - 1)]
    tg_all = _grid(duration, rg)
    times = np.asarray(times, dtype=float)
    counts = np.searchsorted(tg_all, times + 1e-9, side='right')
    out = [np.zeros((9, 9)) for _ in times]
    use = np.flatnonzero(counts >= 3)
    if use.size == 0:
        return out
    order = use[np.argsort(times[use], kind='stable')]
    t_last = float(np.max(times[use]))
    keep = ts <= t_last + 1e-9
    infos = cumulative_information(
        tg_all[:int(np.max(counts))], ts[keep], cmd_s[keep], body,
        np.asarray(lim.initial_omega), times[order],
        gyro_std=lim.gyro_noise * math.sqrt(rg / lim.gyro_rate),
        torque_std=t_std * math.sqrt(rt / lim.torque_rate))
    for k, F in zip(order, infos, strict=True):
        out[int(k)] = F
    return out


# --------------------------------------------------------------------------------------------
# criterion
# --------------------------------------------------------------------------------------------

def theta_covariance(information: np.ndarray, model: str) -> np.ndarray:
    """Bound on the covariance of ``theta`` [kg^2 m^4], shape (6, 6), from ``[theta, w0]``
    information (9, 9); ``model='diagonal'`` drops the products (their rows are zero).
    Infinite diagonal when the information is singular."""
    keep = _DIAG_KEEP if model == 'diagonal' else np.arange(information.shape[0])
    F = information[np.ix_(keep, keep)]
    d = np.sqrt(np.clip(np.diag(F), 0, None))
    cov = np.zeros((6, 6))
    n_th = 3 if model == 'diagonal' else 6
    if np.any(d <= 0) or np.linalg.cond(F / np.outer(d, d)) > 1e14:
        cov[np.arange(n_th), np.arange(n_th)] = np.inf
        return cov
    c = np.linalg.inv(F / np.outer(d, d)) / np.outer(d, d)
    cov[:n_th, :n_th] = c[:n_th, :n_th]
    return cov


def principal_std(inertia: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """First-order std [kg m^2] of the ascending principal moments, shape (3,).

    ``d lambda_k / d theta = [vx^2, vy^2, vz^2, 2 vx vy, 2 vx vz, 2 vy vz]`` with ``v`` the
    k-th principal axis; ``cov`` (6, 6) is the covariance of ``theta``.
    """
    _, v = np.linalg.eigh(inertia)
    J = np.stack([v[0] ** 2, v[1] ** 2, v[2] ** 2, 2 * v[0] * v[1], 2 * v[0] * v[2],
                  2 * v[1] * v[2]], axis=1)                    # (3 moments, 6)
    if not np.all(np.isfinite(cov)):
        return np.full(3, np.inf)
    return np.sqrt(np.clip(np.einsum('ki,ij,kj->k', J, cov, J), 0, None))


def targeted_rel_std(cov: np.ndarray, inertia: np.ndarray, elements: Sequence[str]
                     ) -> dict[str, float]:
    """Relative std of each targeted quantity: ``I1 I2 I3`` for ``principal``, element names
    otherwise (a product against ``trace / 3``)."""
    out: dict[str, float] = {}
    lam = np.linalg.eigvalsh(inertia)
    for e in elements:
        if e == 'principal':
            ps = principal_std(inertia, cov)
            out.update({f'I{k + 1}': float(ps[k] / lam[k]) for k in range(3)})
        else:
            i = THETA_NAMES.index(e)
            scale = inertia[i, i] if i < 3 else np.trace(inertia) / 3.0
            out[e] = float(math.sqrt(cov[i, i]) / scale)
    return out


def criterion(information: np.ndarray, inertia: np.ndarray, target: Target, model: str
              ) -> float:
    """The largest targeted relative std (dimensionless): lower is better."""
    cov = theta_covariance(information, model)
    return max(targeted_rel_std(cov, inertia, target.elements).values())


def time_to_reach(times: np.ndarray, crit: np.ndarray, goal: float) -> float:
    """First time [s] the criterion reaches ``goal`` (log-log interpolation), or inf."""
    ok = np.flatnonzero(crit <= goal)
    if ok.size == 0:
        return math.inf
    k = int(ok[0])
    if k == 0 or not math.isfinite(crit[k - 1]):
        return float(times[k])
    x0, x1 = math.log(times[k - 1]), math.log(times[k])
    y0, y1 = math.log(crit[k - 1]), math.log(crit[k])
    return float(math.exp(x0 + (math.log(goal) - y0) * (x1 - x0) / (y1 - y0)))


# --------------------------------------------------------------------------------------------
# the plan
# --------------------------------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class Plan:
    """A designed excitation and its predictions.

    Attributes
    ----------
    profile : Profile
        The planned profile, within the limits: the designed multisine or a standard profile
        (:func:`_robust_pick`).
    design : dict
        ``family``: ``multisine`` or the standard profile's name; for a multisine its
        parameters (``f0`` Hz, ``n_per_axis``, ``decay``, ``quadrature``, ``spread``,
        ``stagger``: :func:`.profiles.multisine`); for a precision target ``check``, the
        times on the bodies drawn from the prior (:func:`_robust_pick`).
    model : str
        ``full`` or ``diagonal``: the model whose information the plan uses (run the
        estimator with it).
    duration : float
        Suggested manoeuvre length [s]: the time to target (rounded up), or the target
        duration.
    time_to_target : float
        Predicted time [s] at which every targeted relative std reaches the target (prior
        value body); ``nan`` for a duration target.
    times : numpy.ndarray, shape (K,)
        Times [s] of the predicted curves.
    element_std : numpy.ndarray, shape (K, 6)
        Predicted std of ``theta`` [kg m^2] against time.
    principal_std : numpy.ndarray, shape (K, 3)
        Predicted std of the principal moments [kg m^2] against time.
    criterion : numpy.ndarray, shape (K,)
        Largest targeted relative std against time.
    peak_rate : float
        Simulated peak ``|omega|`` [rad/s] over the prior bodies.
    comparison : list of dict
        One row per profile (the planned one first, then the designed multisine if a
        standard profile won, then the other standard profiles): ``name``, ``criterion``
        (worst over the prior bodies at the horizon), ``time_to_target`` [s] (inf when not
        reached within ``max_duration``), ``peak_rate`` [rad/s], ``peak_torque`` [N m] per
        axis.
    horizon : float
        Length [s] at which the candidates were compared.
    usage : dict
        Share of each limit the designed profile uses over the span it was sized for (the
        target duration or ``max_duration``; :func:`limit_usage`).
    binding : str
        The limits the design is held by (:func:`binding_limits` of ``usage``).
    """

    profile: Profile
    design: dict[str, Any]
    model: str
    duration: float
    time_to_target: float
    times: np.ndarray
    element_std: np.ndarray
    principal_std: np.ndarray
    criterion: np.ndarray
    peak_rate: float
    comparison: list[dict[str, Any]] = field(default_factory=list)
    horizon: float = 0.0
    usage: dict[str, float] = field(default_factory=dict)
    binding: str = ''


def choose_model(prior: Prior, target: Target) -> str:
    """``diagonal`` for a principal-moments target on a near-diagonal prior (module
    docstring), else ``full``."""
    if tuple(target.elements) != ('principal',) or not prior.near_diagonal():
        return 'full'
    lam = np.linalg.eigvalsh(prior.inertia)
    shift = np.max(np.abs(lam - np.sort(np.diag(prior.inertia))) / lam)
    if target.rel_std is not None and shift > target.rel_std / 4:
        return 'full'
    return 'diagonal'


def _score(profile: Profile, bodies: Sequence[np.ndarray], lim: Limits, target: Target,
           model: str, horizon: float, rate: float, seed: int) -> tuple[Profile, float, float]:
    """Limit ``profile`` on ``bodies``; its worst criterion over them at ``horizon``."""
    prof, pk = enforce_limits(profile, bodies, lim, horizon, rate, seed)
    worst = 0.0
    for body in bodies:
        F = information_at(prof, body, lim, horizon, [horizon], rate, seed)[0]
        worst = max(worst, criterion(F, body, target, model))
    return prof, worst, pk


def _curve(profile: Profile, prior: Prior, lim: Limits, target: Target, model: str,
           t_end: float, rate: float, seed: int, n: int = 14
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Times and predicted element std, principal std and criterion on the prior value."""
    t0 = max(4.0 / rate, t_end / 100.0)
    times = np.geomspace(t0, t_end, n)
    el, pr, cr = [], [], []
    for F in information_at(profile, prior.inertia, lim, t_end, times, rate, seed):
        cov = theta_covariance(F, model)
        el.append(np.sqrt(np.diag(cov)))
        pr.append(principal_std(prior.inertia, cov))
        cr.append(max(targeted_rel_std(cov, prior.inertia, target.elements).values()))
    return times, np.array(el), np.array(pr), np.array(cr)


def _design(prior: Prior, bodies: list[np.ndarray], lim: Limits, target: Target, model: str,
            horizon: float, rate: float, seed: int) -> list[tuple[dict[str, Any], Profile]]:
    """The best three candidates, best first: scored on the prior value, the best four on
    every prior body (worst case), the best one's base frequency refined."""
    scored = []
    for par, prof in design_candidates(prior, lim, horizon, rate):
        limited, crit, _ = _score(prof, bodies[:1], lim, target, model, horizon, rate, seed)
        scored.append((crit, par, prof))
    scored.sort(key=lambda s: s[0])
    robust = sorted(((_score(prof, bodies, lim, target, model, horizon, rate, seed)[1], i,
                      par, prof) for i, (_, par, prof) in enumerate(scored[:4])),
                    key=lambda s: (s[0], s[1]))
    crit, _, par, prof = robust[0]

    def cost(log_f: float) -> float:
        cand = _from({**par, 'f0': math.exp(log_f)})
        return _score(cand, bodies, lim, target, model, horizon, rate, seed)[1]

    lf = math.log(par['f0'])
    res = minimize_scalar(cost, bounds=(lf - 0.5, lf + 0.5), method='bounded',
                          options={'maxiter': 8, 'xatol': 0.03})
    if res.fun < crit:
        par = {**par, 'f0': float(math.exp(res.x))}
        prof = _from(par)
    return [(par, prof)] + [(r[2], r[3]) for r in robust[1:3]]


def _horizon(prior: Prior, lim: Limits, target: Target, model: str, t_end: float,
             rate: float, seed: int) -> float:
    """Design horizon [s]: the target duration, or the time to target of a harmonic
    multisine at the corner frequency (at least 5 s, at most ``HORIZON_MAX``)."""
    if target.rel_std is None:
        return t_end
    h0 = min(t_end, HORIZON_MAX)
    guess = multisine(max(corner_frequency(prior, lim), 1.0 / h0), 1, 0.0, True)
    limited, _ = enforce_limits(guess, [prior.inertia], lim, t_end, rate, seed)
    times, _, _, crit = _curve(limited, prior, lim, target, model, t_end, rate, seed, n=10)
    t_guess = time_to_reach(times, crit, target.rel_std)
    return float(np.clip(t_guess, 5.0, h0)) if math.isfinite(t_guess) else h0


def _row(name: str, prof: Profile, bodies: list[np.ndarray], prior: Prior, lim: Limits,
         target: Target, model: str, t_end: float, horizon: float, rate: float, seed: int
         ) -> tuple[dict[str, Any], Profile, tuple[np.ndarray, ...]]:
    """A comparison row: the profile limited over ``t_end`` and its predictions."""
    limited, pk = enforce_limits(prof, bodies, lim, t_end, rate, seed)
    _, crit, _ = _score(prof, bodies, lim, target, model, horizon, rate, seed)
    curve = _curve(limited, prior, lim, target, model, t_end, rate, seed)
    goal = target.rel_std if target.rel_std is not None else -1.0
    ttt = time_to_reach(curve[0], curve[3], goal) if goal > 0 else math.nan
    cmd = limited.torque(_grid(t_end, lim.torque_rate), t_end, seed)
    row = {'name': name, 'criterion': crit, 'criterion_at_end': float(curve[3][-1]),
           'time_to_target': ttt, 'peak_rate': pk,
           'peak_torque': [float(v) for v in np.max(np.abs(cmd), axis=0)]}
    return row, limited, curve


def simulated_peak_rate(profile: Profile, bodies: Sequence[np.ndarray], lim: Limits,
                        duration: float, seed: int = 0) -> float:
    """Peak true ``|omega|`` [rad/s] of the project's simulator playing the profile's scene on
    each body (:func:`scene_dict`, :func:`.simulation.simulate`)."""
    from ..scene import Scene
    from ..simulation import simulate

    worst = 0.0
    for body in bodies:
        sim = simulate(Scene.from_dict(scene_dict(profile, lim, duration, body, seed)), seed)
        worst = max(worst, float(np.max(np.linalg.norm(sim.omega_true, axis=1))))
    return worst


def check_times(profile: Profile, bodies: Sequence[np.ndarray], lim: Limits, target: Target,
                model: str, t_end: float, rate: float, seed: int = 0, n: int = 48
                ) -> np.ndarray:
    """Predicted time to target [s] of the (already limited) ``profile`` on each body, (B,):
    the Cramer-Rao criterion at ``n`` times from ``t_end / 30`` to ``t_end`` in one filter
    pass per body; inf where it is not reached by ``t_end``."""
    times = np.geomspace(max(4.0 / rate, t_end / 30.0), t_end, n)
    out = []
    for body in bodies:
        crit = [criterion(F, body, target, model)
                for F in information_at(profile, body, lim, t_end, times, rate, seed)]
        out.append(time_to_reach(times, np.array(crit), target.rel_std))
    return np.array(out)


def _robust_pick(cands: list[Any], n_designed: int, prior: Prior, lim: Limits,
                 target: Target, model: str, t_end: float, rate: float, seed: int
                 ) -> tuple[int, dict[str, Any]]:
    """Index of the plan's profile among ``cands`` (the first ``n_designed`` designed, then
    the standard ones) by time to target on :data:`N_CHECK` bodies drawn from the prior.

    Each profile's regret is its largest ratio over the bodies of its time to the best
    standard profile's on that body (1: never later than the best standard; a designed one
    pays :data:`DOMINANCE_MARGIN` more, so it is planned over a standard that is never
    behind the others only when it is that much sooner on every body).  The smallest regret
    wins, then the smallest median time.  Several standard profiles may each be ahead on
    some of the bodies (as PRBS and the sines when only the torque limit binds): then no
    profile has regret 1 and a designed one may still win.  Only the standard profiles
    within ``CHECK_SHARE`` of the best time on the prior value are timed.
    Returns the index and a summary (``check_bodies``, ``median``, ``q10``, ``q90`` [s] of
    the pick, ``dominates``: a designed one, sooner than the best standard on every body by
    the margin, ``medians``: profile name -> median time [s] of every timed profile).
    """
    t0 = np.array([c[1][0]['time_to_target'] for c in cands])
    best0 = float(np.min(t0))
    if not math.isfinite(best0):
        return 0, {}
    t_chk = min(t_end, 2.0 * best0 * CHECK_SHARE)
    bodies = prior.bodies(N_CHECK + 1, seed + 7919)[1:]
    timed = [i for i in range(len(cands)) if i < n_designed or t0[i] <= CHECK_SHARE * best0]
    T = {i: check_times(cands[i][1][1], bodies, lim, target, model, t_chk, rate, seed)
         for i in timed}
    std = [i for i in timed if i >= n_designed]
    if not std:
        std = [n_designed]
        T[n_designed] = np.full(len(bodies), np.inf)
    s_best = np.min(np.array([T[i] for i in std]), axis=0)

    def regret(i: int) -> float:
        fin = np.isfinite(T[i])                           # reached where s_best is not: 0
        r = np.where(fin, 0.0, np.where(np.isfinite(s_best), np.inf, 1.0))
        ok = np.isfinite(s_best) & fin
        r[ok] = T[i][ok] / s_best[ok]
        return float(np.max(r)) + (DOMINANCE_MARGIN if i < n_designed else 0.0)

    k = min(T, key=lambda i: (regret(i), float(np.median(T[i])), i))
    good = k < n_designed and regret(k) <= 1.0
    q = (np.quantile(T[k], [0.1, 0.5, 0.9]).tolist() if np.all(np.isfinite(T[k]))
         else [None] * 3)                                  # None: not reached on some body
    medians = {cands[i][1][1].name: float(np.median(T[i])) if np.all(np.isfinite(T[i]))
               else None for i in timed}
    return k, {'check_bodies': len(bodies), 'q10': q[0], 'median': q[1], 'q90': q[2],
               'dominates': bool(good), 'medians': medians}


def _candidates(prior: Prior, bodies: list[np.ndarray], lim: Limits, target: Target,
                model: str, t_end: float, horizon: float, rate: float, seed: int
                ) -> tuple[dict[str, Any], tuple[Any, ...], list[dict[str, Any]]]:
    """The plan's profile: one of :func:`_design`'s multisines or a standard profile at the
    same limits.  For a precision target :func:`_robust_pick` decides (time to target on
    bodies drawn from the prior); for a duration target the smallest worst criterion over
    the prior bodies at the horizon (the designed one on a tie).

    Returns the winner's design (``family``: ``multisine`` or the standard profile's name,
    with ``check``: :func:`_robust_pick`'s summary), its :func:`_row` and the comparison
    rows of the others (the best designed one first).
    """
    designed = []
    for par_i, prof_i in _design(prior, bodies, lim, target, model, horizon, rate, seed):
        designed.append(({'family': 'multisine', **par_i},
                         _row('designed', prof_i, bodies, prior, lim, target, model, t_end,
                              horizon, rate, seed)))
        if target.rel_std is None:
            break                     # a duration target: the criterion decided already
    designed.sort(key=lambda c: c[1][0]['time_to_target'])   # stable: design order on ties
    cands = designed + [({'family': p.name}, _row(p.name, p, bodies, prior, lim, target, model,
                                                  t_end, horizon, rate, seed))
                        for p in standard_profiles(lim.max_torque)]
    nd = len(designed)
    if target.rel_std is None:
        cands = cands[:1] + cands[nd:]
        nd = 1
        k = min(range(len(cands)), key=lambda i: (cands[i][1][0]['criterion'], i))
        check: dict[str, Any] = {}
    else:
        k, check = _robust_pick(cands, nd, prior, lim, target, model, t_end, rate, seed)
    # the comparison: the best designed one (when not the pick), then the standard ones
    shown = [i for i in [0] + list(range(nd, len(cands))) if i != k]
    others = [{**cands[i][1][0], 'name': cands[i][1][1].name if i < nd
               else cands[i][1][0]['name']} for i in shown]
    return {**cands[k][0], **({'check': check} if check else {})}, cands[k][1], others


def plan(prior: Prior, lim: Limits, target: Target, *, n_bodies: int = 3, seed: int = 0,
         compare: bool = True) -> Plan:
    """Design an excitation for ``target`` within ``lim``, robust over ``prior``.

    Parameters
    ----------
    prior : Prior
        Prior tensor and its uncertainty (:func:`make_prior`).
    lim : Limits
        Torque, body-rate and sensor figures.
    target : Target
        Precision (or duration) and the longest acceptable manoeuvre.
    n_bodies : int
        Bodies the design must work for: the prior value and ``n_bodies - 1`` draws.
    seed : int
        Seed of the prior draws and of the random standard profiles.
    compare : bool
        Also evaluate the standard profiles (:func:`standard_profiles`).

    Returns
    -------
    Plan

    Raises
    ------
    ValueError
        The target is not reached within ``max_duration`` at these limits (the message says
        what it reaches and what to change).
    """
    model = choose_model(prior, target)
    rate = min(DESIGN_RATE_MAX, lim.gyro_rate, lim.torque_rate)
    bodies = prior.bodies(max(1, n_bodies), seed)
    t_end = target.duration if target.duration is not None else target.max_duration
    horizon = min(t_end, _horizon(prior, lim, target, model, t_end, rate, seed))
    par, (row, limited, curve), others = _candidates(prior, bodies, lim, target, model,
                                                     t_end, horizon, rate, seed)
    ttt = row['time_to_target']
    if target.rel_std is not None and not math.isfinite(ttt):
        raise ValueError(
            f'target not reachable: the designed profile reaches {100 * curve[3][-1]:.3g} % '
            f'(target {100 * target.rel_std:g} %) in the maximum duration '
            f'{target.max_duration:g} s at max torque {list(lim.max_torque)} N m and max rate '
            f'{lim.max_rate:g} rad/s' + (f' with {len(lim.wheels)} wheels (their torque and '
                                         'speed limits)' if lim.wheels else '')
            + (' with the rotors\' speed ranges' if lim.rotors is not None else '')
            + '; raise --max-duration, --max-torque (or the wheels\' or rotors\' limits) '
            'or --max-rate, lower the sensor noise, or relax --target-rel-std')
    duration = t_end if target.duration is not None else min(
        target.max_duration, float(math.ceil(1.1 * ttt)))
    pk = simulated_peak_rate(limited, bodies, lim, duration, seed)
    if pk > lim.max_rate:           # the held command at full rate swings a little further
        w0 = float(np.linalg.norm(lim.initial_omega))
        limited = limited.scaled(RATE_MARGIN * (lim.max_rate - w0) / (pk - w0))
        curve = _curve(limited, prior, lim, target, model, t_end, rate, seed)
        ttt = time_to_reach(curve[0], curve[3], target.rel_std) if target.rel_std else math.nan
        pk = simulated_peak_rate(limited, bodies, lim, duration, seed)
    rows = [{**row, 'name': limited.name, 'time_to_target': ttt, 'peak_rate': pk}]
    if compare:
        rows += others
    usage = limit_usage(limited, bodies, lim, t_end, seed)
    return Plan(profile=limited, design=par, model=model, duration=duration,
                time_to_target=ttt if target.rel_std is not None else math.nan,
                times=curve[0], element_std=curve[1], principal_std=curve[2],
                criterion=curve[3], peak_rate=pk, comparison=rows, horizon=horizon,
                usage=usage, binding=binding_limits(usage))
