"""When an online estimator re-runs model selection and the adequacy test: :class:`Reselection`.

Model selection (``model`` or ``torque_bias`` ``'auto'``) and the window adequacy test cost
several fits; the online estimators run them on every ``every``-th estimate and reuse their
verdicts in between (one fit per estimate otherwise).  With ``defer`` a test estimate reports
the previous adequacy verdict and leaves its own test to :meth:`Reselection.refresh` (the
node calls it after publishing).  A verdict on fewer than ``1 - STALE_FRACTION`` of the
samples an estimate has is not reused: the test runs on that estimate's data (on a short
record the last second changes what the tests see; from ``every / STALE_FRACTION`` estimates
on, never); nor is a model selection (nor the stated inputs' profile,
:mod:`.online_stated`: one from the first second of a 4 s wheel log left the fit's residuals
12x the noise model at its end, which the reused verdict hid).  The schedule owns its state;
the tests themselves are passed in as callables.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np

from .adequacy import Adequacy
from .assemble import conclude
from .fit import Fit
from .model import model_parts
from .result import InertiaEstimate
from .selection import SelectionPolicy

__all__ = ['STALE_FRACTION', 'Reselection']

#: Largest share of an estimate's samples its adequacy verdict may not have seen.
STALE_FRACTION = 0.1

#: The window adequacy test of a fit: ``test(f, gyro_var, torque_var)``.
AdequacyTest = Callable[[Fit, np.ndarray, np.ndarray], Adequacy]


class Reselection:
    """The re-selection schedule of model selection and the adequacy test.

    Parameters
    ----------
    every : int
        Run the selection and the test on every ``every``-th estimate (>= 1).
    defer : bool
        Leave a test estimate's adequacy test to :meth:`refresh`.
    """

    def __init__(self, every: int, defer: bool) -> None:
        if isinstance(every, bool) or int(every) != every or every < 1:
            raise ValueError(f'reselect_every: must be an integer >= 1, got {every!r}')
        self.every = int(every)
        self.defer = bool(defer)
        self.reset()

    def reset(self) -> None:
        """Forget every verdict."""
        self.adequacy: Adequacy | None = None   # last adequacy result, reused between tests
        self.adequacy_left = 0
        #: deferred adequacy test: (estimate serial, final fit, gyro and torque noise variances,
        #: samples)
        self.due: tuple[int, Fit, np.ndarray, np.ndarray, int] | None = None
        self.tested_at = 0               # samples the adequacy verdict saw
        self.estimates = 0               # estimate() calls (serial of the last one)
        # model selection reused between re-selections: (torque_bias, model, its record,
        # inertial_torque)
        self.selection: tuple[str, str, dict[str, Any], str] | None = None
        self.selection_left = self.selected_at = 0   # (and the samples it saw)
        self.disturbance: dict[str, Any] | None = None   # its diagnostics['disturbance']

    def reset_verdicts(self) -> None:
        """Drop the reused selection and adequacy verdicts (the statistics they judged changed:
        another hold); the serial count goes on."""
        self.adequacy, self.adequacy_left, self.due = None, 0, None
        self.selection, self.selection_left = None, 0

    def tick(self) -> None:
        """A new estimate begins."""
        self.estimates += 1

    def window_adequacy(self, f: Fit, nv: np.ndarray, tv: np.ndarray,
                        test: AdequacyTest, samples: int = 0) -> Adequacy:
        """The adequacy verdict for ``f`` (fitted on ``samples`` samples): ``test`` run every
        ``every`` estimates, reused in between (with ``defer`` also at a test estimate, the
        test left to :meth:`refresh`) unless stale (:data:`STALE_FRACTION`)."""
        if (self.due is not None and self.due[0] != self.estimates) or (
                samples - self.tested_at > STALE_FRACTION * samples):
            self.due = None         # owed by an earlier estimate, or stale: test these data
        elif self.adequacy is not None and self.adequacy_left > 0:
            self.adequacy_left -= 1
            return self.adequacy
        elif self.defer and self.adequacy is not None:
            self.due = (self.estimates, f, nv, tv, samples)   # the last call's fit wins
            return self.adequacy
        self.adequacy, self.tested_at = test(f, nv, tv), samples
        self.adequacy_left = self.every - 1
        return self.adequacy

    def refresh(self, test: AdequacyTest) -> bool:
        """Run the deferred adequacy test, if any; True when one ran."""
        if self.due is None:
            return False
        (_, f, nv, tv, self.tested_at), self.due = self.due, None
        self.adequacy = test(f, nv, tv)
        self.adequacy_left = self.every - 1
        return True

    def decide(self, fit: Any, model: str, torque_bias: str, axis: np.ndarray | None,
                 policy: SelectionPolicy, diag: dict[str, Any], base: dict[str, Any],
                 adequacy: Any, sensitivity: Any, samples_used: int) -> InertiaEstimate:
        """Model selection (the last choice reused between re-selections) and the result
        (:func:`.assemble.conclude`)."""
        auto = 'auto' in (model, torque_bias, policy.inertial_torque)
        fresh = samples_used - self.selected_at <= STALE_FRACTION * samples_used
        if auto and self.selection is not None and self.selection_left > 0 and fresh:
            self.selection_left -= 1
            bias, chosen, record, inertial = self.selection
            kept = policy if policy.inertial_torque == 'off' else replace(
                policy, inertial_torque=inertial)      # (the disturbance chosen with it)
            est = conclude(fit, chosen, bias, axis, kept,
                           dict(diag, warnings=list(diag['warnings'])), base, adequacy,
                           sensitivity, by_test=True)
            if est.status in ('ok', 'model_mismatch'):   # (this fit's held covariance)
                est.diagnostics['model_selection'] = dict(
                    record, **est.diagnostics.get('model_selection', {}), reused=True)
                if self.disturbance is not None:          # (the choice's record)
                    est.diagnostics['disturbance'] = dict(self.disturbance, reused=True)
                return est
        est = conclude(fit, model, torque_bias, axis, policy, diag, base, adequacy,
                       sensitivity)
        self.selection = None
        if auto and est.status in ('ok', 'model_mismatch'):
            record = dict(est.diagnostics.get('model_selection') or {},
                          selected_at_samples=samples_used)
            est.diagnostics['model_selection'] = record
            name, bias, inertial = model_parts(est.model)
            self.selection = ('on' if bias else 'off', name, record,
                              'on' if inertial else 'off')
            self.disturbance = est.diagnostics.get('disturbance')
            self.selection_left, self.selected_at = self.every - 1, samples_used
        return est
