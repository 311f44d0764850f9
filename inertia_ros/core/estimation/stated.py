"""Stated input uncertainties of a momentum input, profiled under their prior.

A stated uncertainty (a wheel's spin inertia, a rotor's ``k_f``, ``k_m`` or ``J``, the gyro
scale) is an unknown error ``u_j`` of one stated sigma per unit, ``u ~ N(0, 1)``.  Its effect on
the anchored equations is known to first order: the column ``c_j`` (n, 3) is the change of the
equation error ``X(w) theta - Y`` (``X`` the angular-momentum side, ``Y`` the known angular
impulse ``int tau - dh - int w x h``) for ``u_j = 1``: ``-dY/dp_j`` for an input of ``Y``; for
the gyro scale also the change of the measured rate in ``X`` and in ``w x h``.

:func:`propagate` takes the posterior mean ``u_hat`` and covariance ``cov_u`` of ``u`` from
the online profile (:func:`.online_stated.profile`) on the statistics the online estimator
accumulates over the whole record (one computation, batch and online).  It corrects the inputs
by ``u_hat`` (so the adequacy tests see no residual the stated uncertainty explains) and adds
``D cov_u D'`` to the estimate's covariance (``D`` its sensitivity to ``u``), which in the
linear Gaussian model is exactly the marginal covariance of the tensor: never smaller than
with the inputs known exactly.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from functools import cached_property
from typing import Any

import numpy as np

from .model import model_parts
from .momentum import Momentum, Reduction
from .regressors import cumulative_monomials, gyroscopic_matrix, momentum_matrix
from .uncertainty import widen

__all__ = ['Stated', 'lhs_columns', 'propagate', 'rerun', 'widened']

_MIN_INFORMATION = 4.0          # data information per prior information kept
_UPDATES = 4
_BLOCK_S = 10.0                 # the record fed to the online profile in blocks of this [s]


def lhs_columns(t: np.ndarray, w: np.ndarray) -> np.ndarray:
    """``d/d theta_j`` of ``I w(t) + int_0^t w x I w`` (n, 3, 6) [rad/s, rad] at the gyro
    stamps ``t`` (n,) [s] for the rates ``w`` (n, 3) [rad/s]: the estimator's integral
    (:func:`.regressors.cumulative_monomials`) without its end correction.

    The nuisance fit's interval design: with the end correction its reports move by up to
    1e-2 relative (p-values) and 2e-3 (statistics) on the sample bags with ``--nuisance
    auto`` (issue 26, rule (b): a fold that moves reported numbers is left as it was).
    """
    return momentum_matrix(w) + gyroscopic_matrix(cumulative_monomials(t, w, end_correction=False))


def _larger(M: np.ndarray, H: np.ndarray) -> np.ndarray:
    """The clustered meat ``M``, never below the white-noise one ``H`` along any direction
    (a few clusters can understate it): ``H^1/2 max(1, eig(H^-1/2 M H^-1/2)) H^1/2``."""
    lam, V = np.linalg.eigh(H)
    lam = np.maximum(lam, 1e-12 * max(float(lam.max()), 1e-300))
    R = V * np.sqrt(lam)
    Ri = V / np.sqrt(lam)
    mu, U = np.linalg.eigh(Ri.T @ M @ Ri)
    return R @ (U * np.maximum(mu, 1.0)) @ U.T @ R.T


@dataclass(frozen=True)
class Stated:
    """A momentum input's data with its stated uncertainties.

    ``tg``, ``w`` (n,), (n, 3): the gyro samples inside the coverage [s], [rad/s]; ``ts``,
    ``tau``: the other torque [s], [N m]; ``mom``: the momentum input (its ``h_std`` and
    ``torque_std`` one-sigma changes); ``hold``: the other torque's hold; ``scale`` and
    ``gscale``: the stated relative torque-sensor and gyro scale sigmas (0: none).
    """

    tg: np.ndarray
    w: np.ndarray
    ts: np.ndarray
    tau: np.ndarray
    mom: Momentum
    hold: str
    scale: float = 0.0
    gscale: float = 0.0

    @property
    def names(self) -> list[str]:
        """The stated inputs, in the order of ``u``."""
        return (list(self.mom.names) + ['torque_scale'] * bool(self.scale)
                + ['gyro_scale'] * bool(self.gscale))

    def data(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray | None,
                                            np.ndarray]:
        """``(w, h, torque on the momentum stamps, other torque)`` with the stated inputs
        ``u`` (q,) sigmas off: the true rates of a gyro that reads ``1 + u g`` times high."""
        m, p = self.mom, len(self.mom.names)
        h = m.h + np.tensordot(u[:p], m.h_std, axes=1)
        tq = None if m.torque is None else m.torque + np.tensordot(u[:p], m.torque_std, axes=1)
        tau = self.tau * (1.0 + u[p] * self.scale) if self.scale else self.tau
        w = self.w / (1.0 + u[-1] * self.gscale) if self.gscale else self.w
        return w, h, tq, tau

    @cached_property
    def reduction(self) -> Reduction:
        """:func:`.momentum.equivalent_torque` on these stamps (grid and weights once)."""
        return Reduction(self.tg, self.mom.t, self.ts, self.hold)

    def torque(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Rates (n, 3), grid (G,) and equivalent torque (G, 3) with the inputs ``u`` off."""
        w, h, tq, tau = self.data(u)
        grid, out, _ = self.reduction(w, h, tau, tq)
        return w, grid, out


def _profile(res: Any, st: Stated, gyro_noise: Any = None) -> tuple[np.ndarray, np.ndarray]:
    """The posterior mean (q,) and covariance (q, q) of the stated inputs: the online
    profile (:func:`.online_stated.profile`) on the statistics the online estimator
    (:class:`.recursive_momentum.MomentumRecursiveEstimator`) accumulates over the whole
    record, with ``res``'s segmentation, bias and tensor (one computation, batch and online,
    so the two agree by construction)."""
    from .recursive_momentum import MomentumRecursiveEstimator

    m, other = st.mom, len(st.ts) > 0
    est = MomentumRecursiveEstimator(
        names=m.names, other_torque=other, hold=st.hold, torque_scale_std=st.scale,
        gyro_scale_std=st.gscale, gyro_noise=gyro_noise, model='full',
        torque_bias=model_parts(res.model)[1], segment=res.diagnostics.get('segment_s'))
    edges = np.r_[-np.inf, np.arange(st.tg[0], st.tg[-1], _BLOCK_S)[1:], np.inf]
    for a, b in zip(edges[:-1], edges[1:], strict=True):   # under the buffers' bound
        if other:
            est.add_torque(*_block(st.ts, a, b, st.tau))
        t, h, dh, tq, dtq = _block(m.t, a, b, m.h, m.h_std, m.torque, m.torque_std)
        est.add_momentum(replace(m, t=t, h=h, h_std=dh, torque=tq, torque_std=dtq))
        est.add_gyro(*_block(st.tg, a, b, st.w))
    prof = est._stated
    prof.theta = np.asarray(res.theta, dtype=float)
    for _ in range(_UPDATES):
        prof.update(est)
    return prof.u, prof.cov_u


def _block(t: np.ndarray, a: float, b: float, *values: Any) -> list[Any]:
    """``t`` (n,) in ``[a, b)`` and the same samples of each of ``values`` (the stamps on
    their first axis, or their second for (p, n, 3) changes; None stays None)."""
    k = (t >= a) & (t < b)
    return [t[k], *(None if v is None else v[:, k] if v.ndim == 3 else v[k] for v in values)]


def _fixed(res: Any, options: dict[str, Any]) -> dict[str, Any] | None:
    """``res``'s method, model, bias, noise and segments, fixed (None: not propagated)."""
    diag = res.diagnostics
    fixed = dict(options)
    name, bias, inertial = model_parts(res.model)
    fixed.update(method='integral' if res.method == 'ml' else res.method, model=name,
                 torque_bias='on' if bias else 'off',
                 gyro_noise=diag.get('gyro_noise_std'))
    if inertial or 'inertial_torque' in options:      # (the disturbance chosen, fixed too)
        fixed['inertial_torque'] = 'on' if inertial else 'off'
    if diag.get('segment_s') is not None:
        fixed['segment'] = diag['segment_s']
    if diag.get('filter_cutoff_hz'):    # the same band (method='auto' may pick filtered)
        fixed['window'] = 1.0 / float(diag['filter_cutoff_hz'])
    return fixed if fixed['model'] in ('full', 'diagonal', 'axisymmetric') else None


def rerun(res: Any, run: Any, st: Stated, u: np.ndarray, options: dict[str, Any]) -> Any:
    """``run`` with ``options`` on the data with the stated inputs ``u`` (q,) off, keeping
    the other torque's hold chosen for ``res`` (its ``hold`` and ``hold_selection``)."""
    out = run(*st.torque(u), **options)
    for key in ('hold', 'hold_selection'):
        if key in res.diagnostics:
            out.diagnostics[key] = res.diagnostics[key]
    return out


def propagate(res: Any, run: Any, st: Stated, options: dict[str, Any]) -> Any:
    """The estimate with the stated inputs profiled (module docstring).

    The torque path states the same two scales through :func:`.assemble.add_calibration`
    instead, and the two stay apart (issue 26, rule (d)): there no profile is run (the prior
    stands) and ``cov += s^2 beta beta' + g^2 J J'`` with ``J = d beta / d g`` linearised (a
    refit of the gyro-scaled statistics); here the inputs are profiled, then each is moved by
    one stated sigma and the record re-estimated (``D`` by a finite step, ``P + 1`` runs).
    On torque records (30 s, 2 seeds, 2 % torque and 1 % gyro scale; this path fed a zero
    momentum) the profile leaves both at their prior and the estimate unmoved, and the added
    sigmas agree within 0.4 %: not the 1e-6 of a fold.

    Parameters
    ----------
    res : InertiaEstimate
        The estimate with the inputs as stated.
    run : callable
        ``run(w (n, 3), grid (G,), torque (G, 3), **options) -> InertiaEstimate``.
    st : Stated
    options : dict
        The estimate's options.

    Returns
    -------
    InertiaEstimate
        The estimate on the inputs corrected by ``u_hat`` with ``D cov_u D'`` added
        (``diagnostics['input_uncertainty']``, also ``['wheel_inertia']``).
    """
    names = st.names
    u_hat, cov_u = _profile(res, st, options.get('gyro_noise'))
    out = rerun(res, run, st, u_hat, options)
    fixed = _fixed(out, options) if out.inertia is not None \
        and np.all(np.isfinite(out.inertia)) else None
    if fixed is None:
        return res if out.inertia is None else out
    # the reference and the sensitivity runs are used for their tensors alone: without the
    # adequacy tests (which only widen a covariance)
    ref = out if out.method != 'ml' else run(*st.torque(u_hat), **fixed, final=False)
    D = np.zeros((len(names), 6))                   # d theta (6,) per input sigma
    for j in range(len(names)):
        p = run(*st.torque(u_hat + np.eye(len(names))[j]), **fixed, final=False)
        if p.inertia is not None and np.all(np.isfinite(p.inertia)):
            D[j] = np.nan_to_num(p.theta - ref.theta)
    return widened(out, D, u_hat, cov_u, names, 'the accumulated equations (the online '
                   "profile's), the data corrected by the posterior mean", st.scale, st.gscale)


def widened(est: Any, D: np.ndarray, u: np.ndarray, cov_u: np.ndarray, names: list[str],
            where: str, scale: float, gscale: float) -> Any:
    """``est`` with the stated inputs' ``D' cov_u D`` added to its covariance and every
    uncertainty derived from it (:func:`.uncertainty.widen`), and their record, batch and
    online alike.

    ``D`` (q, 6): the change of ``theta`` per stated sigma of each input; ``u`` (q,), ``cov_u``
    (q, q): their posterior mean [stated sigmas] and covariance; ``names`` (q): the inputs;
    ``where``: the equations the profile ran on; ``scale``, ``gscale``: the stated torque and
    gyro scale sigmas.

    The record: ``diagnostics['input_uncertainty']`` (alias ``wheel_inertia``), each input's
    change, profiled and posterior sigmas, the standard errors added (``D cov_u D'``), the
    posterior covariance and the rule; the stated scales in ``diagnostics['calibration']``; a
    ``model_mismatch`` reason says the stated sigmas do not explain it.
    """
    outer = D.T @ cov_u @ D
    per = {nm: {'theta_change': D[j], 'profiled_sigmas': float(u[j]),
                'posterior_sigmas': float(np.sqrt(max(cov_u[j, j], 0.0)))}
           for j, nm in enumerate(names)}
    out = widen(est, outer)
    if out is est:
        out = replace(est, diagnostics=dict(est.diagnostics))
    diag = out.diagnostics
    diag['wheel_inertia'] = {
        'inputs': per, 'theta_std_added': np.sqrt(np.diag(outer)), 'posterior_cov': cov_u,
        'rule': f"stated inputs profiled under their N(0, stated sigma) prior on {where}, "
                "D cov D' added"}
    diag['input_uncertainty'] = diag['wheel_inertia']
    if scale or gscale:
        calib = dict(diag.get('calibration') or {})
        calib.update(torque_scale_std=scale, gyro_scale_std=gscale,
                     applies_to="stated inputs 'torque_scale' (the torque stream only, not the "
                     "momentum input) and 'gyro_scale' (the rate in both sides, w x h "
                     'included) of input_uncertainty')
        diag['calibration'] = calib
    if out.status == 'model_mismatch' and 'reason' in diag:
        diag['reason'] = (f"{diag['reason']}; beyond what the stated wheel inertias / rotor "
                          'coefficients / sensor scales explain')
    return out
