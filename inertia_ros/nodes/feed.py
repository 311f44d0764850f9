"""The ``inertia_estimator`` node's online estimator: fed from the admitted inputs, asked
for estimates, rebuilt on a reset.  No rclpy here.

:class:`EstimatorFeed` owns the core estimator (:mod:`inertia_ros.nodes.selection` picks
it), the torque-free shadow estimator used while no torque message has arrived, and the
node-level reasons of an ``insufficient_data`` estimate (which input is still missing).
"""
from __future__ import annotations

import re
from typing import Any

import numpy as np

from inertia_ros.core.estimation.recursive import RecursiveEstimator
from inertia_ros.core.estimation.result import InertiaEstimate
from inertia_ros.core.estimation.windowed import OnlineEstimator
from inertia_ros.nodes.admission import Admission
from inertia_ros.nodes.selection import (
    make_estimator,
    reselect_every,
    torque_free_estimator,
    torque_topic_is_none,
)

__all__ = ['EstimatorFeed']

#: The core's reason while too few gyro samples are covered by the known torque.
_TOO_FEW = re.compile(r'only (\d+) gyro samples covered by torque so far')


class EstimatorFeed:
    """The online estimator of the node and what feeds it.

    Parameters
    ----------
    cfg : dict
        The node's parameter values (see :func:`inertia_ros.nodes.selection.make_estimator`).
    actuators : inertia_ros.io.rotors.ActuatorInput or None
        The wheels or rotors on the JointState stream.
    admission : Admission
        The admitted inputs (buffered samples, epoch, streams).
    logger : object
        ``error`` with ``throttle_duration_sec`` (an rclpy logger).
    """

    def __init__(self, cfg: dict[str, Any], actuators: Any, admission: Admission,
                 logger: Any) -> None:
        self.cfg = cfg
        self.actuators = actuators
        self.admission = admission
        self.torque_free = torque_topic_is_none(cfg)
        self.factory = make_estimator(cfg, actuators)
        self.estimator: OnlineEstimator = self.factory()
        #: torque-free estimator fed while no torque message has arrived (zero torque)
        self.shadow: OnlineEstimator | None = None
        #: the last estimator exception other than ValueError (a core bug), for diagnostics
        self.core_error: str | None = None
        self._log = logger

    def configure(self, cfg: dict[str, Any], rebuild: bool) -> None:
        """New parameter values: a new factory; with ``rebuild`` the caller resets (the new
        estimator is built by :meth:`reset`), else the estimate is kept and only the
        model-selection period follows the publish rate."""
        self.cfg = cfg
        self.factory = make_estimator(cfg, self.actuators)
        if not rebuild and isinstance(self.estimator, RecursiveEstimator):
            self.estimator.reselect_every = reselect_every(cfg)

    def reset(self) -> None:
        """A new estimator; the shadow and the actuators' motor-lag state forgotten."""
        self.estimator = self.factory()
        if self.actuators is not None:
            self.actuators.reset()
        self.shadow = None

    def incremental(self) -> bool:
        """Whether samples are handed over and merged ahead of the update.

        Only the plain recursive estimator: its statistics do not depend on how the samples
        were cut into blocks (the tracking and momentum estimators get them at the update).
        """
        return type(self.estimator) is RecursiveEstimator

    # ------------------------------------------------------------------ feeding
    def _add_joints(self, t: np.ndarray, speed: np.ndarray) -> None:
        """Hand JointState speeds to the estimator as its momentum input; samples the
        estimator refuses (stamps of an older timeline after a reset) are counted."""
        try:
            self.estimator.add_momentum(self.actuators.block(t, speed))
        except ValueError:
            self.admission.joints.out_of_order += len(t)

    def feed(self) -> None:
        """Hand every buffered sample to the estimator(s).

        Torque-free (``torque_topic: none``): zero torque at the gyro stamps, which is exactly
        the torque-free declaration.  While no torque message has arrived on a torque topic,
        a second estimator gets the same (:attr:`shadow`), so that the node reports ratios
        and axes until the torque stream starts; the first torque message drops it.
        """
        adm = self.admission
        gyro = adm.take(adm.gyro)
        if gyro is not None:
            self.estimator.add_gyro(*gyro)
        torque = adm.torque
        if adm.joints is not None:            # wheels or rotors: no torque-free shadow
            joints = adm.take(adm.joints)
            if joints is not None:
                self._add_joints(*joints)
            if not self.torque_free:
                self._feed_torque()
            return
        if self.torque_free:
            if gyro is not None:
                self.estimator.add_torque(gyro[0], np.zeros_like(gyro[1]))
            return
        if torque.received or torque.before_gyro:
            self.shadow = None
        elif gyro is not None:
            if self.shadow is None:
                self.shadow = torque_free_estimator(self.cfg)()
            self.shadow.add_gyro(*gyro)
            self.shadow.add_torque(gyro[0], np.zeros_like(gyro[1]))
        self._feed_torque()

    def _feed_torque(self) -> None:
        torque = self.admission.take(self.admission.torque)
        if torque is not None:
            self.estimator.add_torque(*torque)

    # ------------------------------------------------------------------ estimating
    def call(self, name: str) -> None:
        """Call the estimator's ``merge`` or ``refresh`` if it has one (off the latency path:
        :meth:`RecursiveEstimator.merge`, :meth:`RecursiveEstimator.refresh`).

        A ValueError is left to the next estimate to report; anything else is a core bug,
        reported as by :meth:`estimate`, never a reason to stop the node.
        """
        call = getattr(self.estimator, name, None)
        if call is None:
            return
        try:
            call()
        except ValueError:
            pass
        except Exception as exc:  # a core bug must not take the node down
            self.core_error = f'estimator error: {type(exc).__name__}: {exc}'
            self._log.error(self.core_error, throttle_duration_sec=5.0)

    def estimate(self) -> InertiaEstimate:
        """The core's estimate; a core error becomes ``insufficient_data`` with its reason.

        ValueError from the core means the data cannot give an estimate yet (too few
        samples, no overlap of the streams); anything else is a bug worth an ERROR
        diagnostic, but never a reason to stop the node.
        """
        try:
            est = self.estimator.estimate()
            self.core_error = None
            if est.status == 'insufficient_data':
                return self._while_waiting(est)
            return est
        except ValueError as exc:
            self.core_error = None
            reason = str(exc)
        except Exception as exc:  # a core bug must not take the node down
            reason = f'estimator error: {type(exc).__name__}: {exc}'
            self.core_error = reason
            self._log.error(reason, throttle_duration_sec=5.0)
        return InertiaEstimate('insufficient_data', method=self.cfg['method'],
                               diagnostics={'reason': reason})

    def _while_waiting(self, est: InertiaEstimate) -> InertiaEstimate:
        """An ``insufficient_data`` estimate with the input it waits for as its reason, or
        the shadow's torque-free estimate while no torque message has arrived."""
        adm = self.admission
        if adm.joints is not None and self.torque_free:
            est.diagnostics['reason'] = self._joints_reason(est.diagnostics.get('reason', ''))
        elif adm.joints is not None and not adm.torque.received:
            kind = self.actuators.kind
            est.diagnostics['reason'] = (
                f'no torque message on {adm.torque.topic} yet: the {kind} input waits for it '
                f'(set torque_topic:=none when the {kind} are the only known torque)')
        if self.shadow is not None:
            free = self.shadow.estimate()
            if free.status != 'insufficient_data':
                free.diagnostics['reason'] = (
                    f'no torque message on {adm.torque.topic} yet: torque-free estimate '
                    '(ratios and principal axes only)')
                return free
        return est

    def _joints_reason(self, reason: str) -> str:
        """What an estimate from the wheels or rotors alone (``torque_topic: none``) waits
        for: the core's "covered by torque" wording names the JointState stream instead."""
        adm, act = self.admission, self.actuators
        joints = f'every joint of {act.file} ({", ".join(act.joints)})'
        if adm.gyro.last_ns is None:
            return f'waiting for gyro messages on {adm.gyro.topic}'
        if not adm.joints.received:
            return (f'waiting for JointState messages on {adm.joints.topic} (the '
                    f"{act.kind}' speeds are the only known torque: torque_topic none)")
        if adm.joints.last_ns is None:
            return (f'waiting for JointState messages on {adm.joints.topic} with a velocity '
                    f'for {joints}')
        m = _TOO_FEW.fullmatch(reason)
        if m is None:
            return reason
        return (f"only {m.group(1)} gyro samples covered by the {act.kind}' speeds on "
                f'{adm.joints.topic} so far: waiting for more gyro and JointState messages')
