"""``inertia_estimator``: the live inertia-tensor estimator node (ROS 2 Jazzy).

Subscribes the gyro stream (``imu``: sensor_msgs/Imu, or ``omega``: geometry_msgs/
Vector3Stamped by parameter) and the torque stream (``torque``: geometry_msgs/WrenchStamped,
or Vector3Stamped by parameter) with sensor-data QoS (best effort, volatile; history depth
``qos_depth``, default 10000: a stall of the node or a burst of the publisher of up to 1.25 s
drops nothing at 8 kHz).  Samples are aligned by their header stamps inside the core
(:mod:`inertia_ros.core.estimation`); this node only converts messages, keeps counts and
publishes:

``~/inertia``            geometry_msgs/InertiaStamped, latched (reliable, transient local,
                         depth 1: a late subscriber gets the last estimate), only while the
                         status is ``ok`` (or ``partially_identifiable`` with
                         ``publish_partial``: NaN elements)
``~/principal_moments``  geometry_msgs/Vector3Stamped [kg m^2], ascending
``~/principal_axes``     geometry_msgs/QuaternionStamped (rotation whose columns are the axes)
``/diagnostics``         diagnostic_msgs/DiagnosticArray once a second (diagnostic_updater
                         convention: status ``'<node name>: inertia estimate'``, hardware_id
                         the node name): status, model, condition number, standard errors,
                         sample counts, the reason when not ok, stream timeouts, refused frames
``~/markers``            visualization_msgs/MarkerArray: ellipsoid, principal axes, omega, L

Service ``~/reset`` (std_srvs/Trigger) forgets every sample.  Every output but the
diagnostics is stamped with the newest input header stamp the estimate has seen.
Robustness: NaN/Inf samples are dropped and counted; samples from another frame than the
gyro's are refused, counted and reported (ERROR diagnostic); a backward jump of the input
stamps larger than ``clock_jump_threshold`` (bag loop, simulator restart) or a backward jump
of the node's ROS clock (``use_sim_time``) resets the estimator cleanly; a stream silent for
``stream_timeout`` raises a WARN diagnostic.

Input is polled: the two subscriptions belong to this node (``ros2 node info`` lists them)
but sit in a callback group no executor waits on (:class:`inertia_ros.nodes._ros.PolledGroup`);
they are drained every ``poll_period`` and each batch is decoded at once
(:mod:`inertia_ros.io.cdr_decode`); at 1 kHz per stream this costs a few times less CPU than
one executor wake-up per message.  After a poll, the estimator is updated and the outputs
published if at least ``1/publish_rate`` seconds (steady clock) have passed since the previous
update, so the newest input waits at most one inter-message gap plus the compute time.
All numerics live in :mod:`inertia_ros.core`; the online estimators behind
:class:`inertia_ros.core.estimation.windowed.OnlineEstimator`.  This module only wires
parameters, topics, timers and services: the estimator is chosen by
:mod:`~inertia_ros.nodes.selection`, the inputs checked and counted by
:mod:`~inertia_ros.nodes.admission`, fed and asked by :mod:`~inertia_ros.nodes.feed`, and the
results published by :mod:`~inertia_ros.nodes.outputs`.
"""
from __future__ import annotations

import math
import threading
import time
from typing import Any

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import Vector3Stamped, WrenchStamped
from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock, ClockChange, JumpThreshold, TimeJump
from rclpy.clock_type import ClockType
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import Imu, JointState
from std_srvs.srv import Trigger

from inertia_ros.core.estimation.result import InertiaEstimate
from inertia_ros.core.estimation.windowed import OnlineEstimator
from inertia_ros.io import cdr_decode
from inertia_ros.nodes import params
from inertia_ros.nodes._ros import (
    PolledGroup,
    polled_subscription,
    run_node,
    sensor_qos,
    take_raw,
)
from inertia_ros.nodes.admission import STAMP_CONFIRM, Admission, InputStream
from inertia_ros.nodes.diagnostics import (
    DIAGNOSTIC_PERIOD,
    diagnostic_array,
    diagnostic_status,
    status_name,
)
from inertia_ros.nodes.feed import EstimatorFeed
from inertia_ros.nodes.outputs import EstimateOutputs, quiet
from inertia_ros.nodes.params import ParamSpec
from inertia_ros.nodes.selection import (
    BATCH_DEFAULT_WINDOW,
    TRACKING_DEFAULT_WINDOW,
    make_estimator,
    no_torque_topic,
    torque_free_estimator,
)

__all__ = ['BATCH_DEFAULT_WINDOW', 'DIAGNOSTIC_TASK', 'NODE_NAME', 'PARAMETERS', 'STAMP_CONFIRM',
           'TRACKING_DEFAULT_WINDOW', 'InertiaEstimatorNode', 'main', 'make_estimator',
           'torque_free_estimator']

NODE_NAME = 'inertia_estimator'
#: Task name of the node's diagnostic status (``'<node name>: <task>'``).
DIAGNOSTIC_TASK = 'inertia estimate'

OMEGA_TYPES = {'imu': (Imu, 'imu', 'sensor_msgs/msg/Imu', 'angular_velocity'),
               'vector3': (Vector3Stamped, 'omega', 'geometry_msgs/msg/Vector3Stamped',
                           'vector')}
TORQUE_TYPES = {'wrench': (WrenchStamped, 'torque', 'geometry_msgs/msg/WrenchStamped',
                           'torque'),
                'vector3': (Vector3Stamped, 'torque', 'geometry_msgs/msg/Vector3Stamped',
                            'vector')}

#: Every parameter of the node (config/inertia_estimator.yaml documents the same set).
PARAMETERS: dict[str, ParamSpec] = params.ESTIMATOR
#: Parameters whose change rebuilds the estimator (a reset).
REBUILD_PARAMETERS = ('method', 'batch_method', 'model', 'symmetry_axis', 'torque_bias',
                      'inertial_torque', 'forgetting', 'window', 'hold', 'torque_scale_std',
                      'gyro_scale_std', 'frame_id')


class InertiaEstimatorNode(Node):
    """ROS 2 wrapper around the core's online inertia estimators (see the module docstring)."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(NODE_NAME, **kwargs)
        cfg = params.declare(self, PARAMETERS)  # one-line ValueError for a bad value
        problem = self._validate(cfg)
        if problem:
            raise ValueError(problem)
        self._cfg = cfg
        self._lock = threading.RLock()
        self._actuators = self._load_actuators(cfg)
        # The subscriptions first: discovery starts now, before anything else is built.
        self._torque_free = no_torque_topic(cfg)
        self._make_inputs(cfg)
        self._feed = EstimatorFeed(cfg, self._actuators, self._admission, self.get_logger())
        self._resets = 0
        self._last_update = -math.inf
        self._last_estimate: InertiaEstimate | None = None
        self._reset_reason: str | None = None
        self._update_ms = 0.0
        self._fed = False                     # samples handed over ahead of the next update
        self._merged = False                  # (and merged: once per update, _maybe_update)
        self._status: str | None = None       # last published status (logged on change)
        self._started = time.monotonic()
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self._make_outputs()
        self.get_logger().info(self._listening_text(cfg))

    def _listening_text(self, cfg: dict[str, Any]) -> str:
        """The start-up line: input topics and types, method, model, torque bias."""
        torque = ('no torque stream (torque_topic none): torque-free estimation'
                  if self._torque_free else
                  f'{self._torque.topic} ({TORQUE_TYPES[cfg["torque_msg_type"]][0].__name__})')
        if self._joints is not None:
            torque += (f' and {self._joints.topic} (JointState: {self._actuators.kind} of '
                       f'{self._actuators.file})')
            if self._torque_free:
                torque = torque.replace('torque-free estimation', f'the {self._actuators.kind}'
                                        ' speeds are the only known torque')
        return (f'listening on {self._gyro.topic} '
                f'({OMEGA_TYPES[cfg["omega_msg_type"]][0].__name__}) and {torque}; '
                f'method={cfg["method"]}, model={cfg["model"]}, '
                f'torque_bias={cfg["torque_bias"]}')

    @staticmethod
    def _load_actuators(cfg: dict[str, Any]) -> Any:
        """The wheels or rotors of ``wheels_file`` / ``rotors_file`` (None: neither); a bad
        file is a one-line ValueError naming the parameter."""
        from inertia_ros.io.rotors import load_actuators

        try:
            return load_actuators(cfg['wheels_file'], cfg['rotors_file'])
        except ValueError as exc:
            name = 'wheels_file' if cfg['wheels_file'] else 'rotors_file'
            raise ValueError(f'parameter {name!r}: {exc}') from None

    def _make_inputs(self, cfg: dict[str, Any]) -> None:
        """The polled input subscriptions, their admission and the steady-clock poll timer."""
        om_type, om_topic, om_cdr, om_field = OMEGA_TYPES[cfg['omega_msg_type']]
        tq_type, tq_topic, tq_cdr, tq_field = TORQUE_TYPES[cfg['torque_msg_type']]
        qos = sensor_qos(int(cfg['qos_depth']))
        polled = PolledGroup()
        self._gyro = InputStream('gyro', om_cdr, om_field,
                                 sub=polled_subscription(self, om_type, om_topic, qos, polled))
        self._torque = InputStream('torque', tq_cdr, tq_field, sub=None if self._torque_free
                                   else polled_subscription(self, tq_type, cfg['torque_topic']
                                                            or tq_topic, qos, polled))
        self._joints = None if self._actuators is None else InputStream(
            'joints', 'sensor_msgs/msg/JointState', 'velocity',
            sub=polled_subscription(self, JointState, 'joint_states', qos, polled))
        self._admission = Admission(self._gyro, self._torque, self._joints,
                                    frame=cfg['frame_id'] or None,
                                    jump_threshold_s=float(cfg['clock_jump_threshold']),
                                    on_reset=self._reset, logger=self.get_logger())
        # Polling and the diagnostics run on the steady clock: with use_sim_time they must
        # not stop when /clock pauses, nor speed up with a fast bag.
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._poll_timer = self.create_timer(float(cfg['poll_period']), self._on_poll,
                                             clock=self._steady)

    def _make_outputs(self) -> None:
        """Publishers, the reset service, the diagnostics timer and the clock-jump handler."""
        self._outputs = EstimateOutputs(self)
        self._pub_diag = self.create_publisher(DiagnosticArray, '/diagnostics', 10, **quiet())
        self._srv_reset = self.create_service(Trigger, '~/reset', self._on_reset)
        self._srv_urdf = self.create_service(Trigger, '~/urdf', self._on_urdf)
        self._diag_timer = self.create_timer(DIAGNOSTIC_PERIOD, self.force_update,
                                             clock=self._steady)
        self._jump_handle = self.get_clock().create_jump_callback(
            JumpThreshold(min_forward=None, min_backward=Duration(nanoseconds=-1_000_000),
                          on_clock_change=True),
            post_callback=self._on_clock_jump)

    # ------------------------------------------------------------------ state for tools
    @property
    def _estimator(self) -> OnlineEstimator:
        """The core's online estimator now in use."""
        return self._feed.estimator

    @property
    def _shadow(self) -> OnlineEstimator | None:
        """The torque-free estimator fed while no torque message has arrived."""
        return self._feed.shadow

    # ------------------------------------------------------------------ parameters
    @staticmethod
    def _validate(cfg: dict[str, Any]) -> str:
        """Return '' when the configuration is valid, else a message naming the problem."""
        for name, p in PARAMETERS.items():
            try:
                params.coerce(name, p, cfg[name])
            except ValueError as exc:
                return str(exc)
        try:
            make_estimator(cfg)
        except ValueError as exc:
            return f'rejected by the estimator: {exc}'
        return ''

    def _on_set_parameters(self, changes: list[Parameter]) -> SetParametersResult:
        """Validate a parameter change; on success rebuild the estimator (a reset)."""
        problem = params.check_changes(PARAMETERS, changes)
        if problem:
            return SetParametersResult(successful=False, reason=problem)
        cfg = dict(self._cfg)
        for p in changes:
            if p.name in PARAMETERS:
                cfg[p.name] = params.coerce(p.name, PARAMETERS[p.name], p.value)
        problem = self._validate(cfg)
        if problem:
            return SetParametersResult(successful=False, reason=problem)
        with self._lock:
            rebuild = any(cfg[k] != self._cfg[k] for k in REBUILD_PARAMETERS)
            if cfg['frame_id'] != self._cfg['frame_id']:
                self._admission.frame = cfg['frame_id'] or None
            rate_changed = cfg['publish_rate'] != self._cfg['publish_rate']
            self._cfg = cfg
            self._admission.jump_threshold_s = float(cfg['clock_jump_threshold'])
            if rebuild or rate_changed:
                # a rate change: the model-selection period follows it, the estimate is kept
                self._feed.configure(cfg, rebuild)
            if rebuild:
                self._reset('parameters changed')
        return SetParametersResult(successful=True)

    # ------------------------------------------------------------------ input
    def _on_poll(self) -> None:
        """Take every queued input message, check and queue the samples, maybe update."""
        for s in (self._gyro, self._torque):
            if s.sub is None:
                continue
            payloads = take_raw(s.sub)
            if payloads:
                self._accept(s, payloads)
        if self._joints is not None:
            payloads = take_raw(self._joints.sub)
            if payloads:
                self._accept_joints(payloads)
        self._maybe_update()

    def _accept(self, s: InputStream, payloads: list[bytes]) -> None:
        """Decode a batch of serialised gyro or torque messages and admit the usable
        samples (:meth:`inertia_ros.nodes.admission.Admission.accept`)."""
        now = time.monotonic()
        batch = cdr_decode.decode_payloads(s.msg_type, payloads, fields=(s.field_name,))
        with self._lock:
            self._admission.accept(s, batch, len(payloads), now)

    def _accept_joints(self, payloads: list[bytes]) -> None:
        """Decode JointState messages and admit the speeds of the file's joints
        (:meth:`inertia_ros.nodes.admission.Admission.accept_joints`)."""
        from inertia_ros.io.joint_state import decode_joint_state

        now = time.monotonic()
        decoded = []
        for data in payloads:
            try:
                decoded.append(decode_joint_state(data))
            except ValueError:
                decoded.append(None)
        with self._lock:
            self._admission.accept_joints(decoded, len(payloads), self._actuators.joints, now)

    # ------------------------------------------------------------------ reset / clock
    def _reset(self, reason: str) -> None:
        """Forget every sample (estimator, pending buffers, epoch); counts are kept."""
        with self._lock:
            self._feed.reset()
            self._admission.clear()
            self._fed = False
            self._last_estimate = None
            self._resets += 1
            self._reset_reason = reason
        self.get_logger().info(f'estimator reset: {reason}')

    def _on_reset(self, request: Trigger.Request, response: Trigger.Response
                  ) -> Trigger.Response:
        self._reset('~/reset service')
        response.success = True
        response.message = f'estimator reset ({self._resets} resets so far)'
        return response

    def _on_urdf(self, request: Trigger.Request, response: Trigger.Response
                 ) -> Trigger.Response:
        """``~/urdf``: the current tensor as a URDF document (mass from ``urdf_mass``)."""
        from inertia_ros.io.urdf import urdf_document

        est = self._last_estimate
        if est is None or est.inertia is None or not np.all(np.isfinite(est.inertia)):
            response.success = False
            response.message = ('no complete tensor yet (status '
                                f'{"none" if est is None else est.status})')
            return response
        try:
            response.message = urdf_document(
                est.inertia, float(self._cfg['urdf_mass']), link=self._cfg['urdf_link'],
                comment=f'inertia_ros live estimate: status {est.status}, model {est.model}')
            response.success = True
        except ValueError as exc:
            response.success = False
            response.message = str(exc).splitlines()[0]
        return response

    def _on_clock_jump(self, jump: TimeJump | dict[str, Any]) -> None:
        """Reset when the ROS clock jumps back (sim time restarted) or changes source."""
        if isinstance(jump, dict):
            change, delta_ns = jump['clock_change'], int(jump['delta'])
        else:
            change, delta_ns = jump.clock_change, jump.delta.nanoseconds
        if change in (ClockChange.ROS_TIME_ACTIVATED, ClockChange.ROS_TIME_DEACTIVATED):
            self._reset(f'clock source changed ({ClockChange(change).name})')
        elif delta_ns < 0:
            self._reset(f'ROS clock jumped back {-delta_ns * 1e-9:.3f} s')

    # ------------------------------------------------------------------ output
    def _maybe_update(self) -> None:
        """Update when samples are pending and the publish period has elapsed.

        At the last poll before an update is due, the samples queued so far are handed to the
        recursive estimator and merged (:meth:`RecursiveEstimator.merge`), so that the update
        itself merges only the newest poll's samples: less work between the newest input and
        the estimate, at the cost of one more hand-over per update.
        """
        if not (self._fed or self._admission.pending()):
            return
        now = time.monotonic()
        due = self._last_update + 1.0 / self._cfg['publish_rate']
        if now >= due:
            self._update(now)
        elif not self._merged and now + 1.5 * self._cfg['poll_period'] >= due \
                and self._feed.incremental():
            with self._lock:
                self._merged = True               # once per update
                if self._admission.epoch_ns is not None and self._admission.pending():
                    self._feed.feed()
                    self._fed = True
                    self._feed.call('merge')

    def _update(self, now: float) -> None:
        """Hand buffered samples to the core, estimate, publish everything."""
        with self._lock:
            self._last_update = now
            self._fed = self._merged = False
            if self._admission.epoch_ns is None:
                return
            self._feed.feed()
            est = self._feed.estimate()
            self._update_ms = (time.monotonic() - now) * 1e3
            self._publish(est, self._admission.newest_stamp())
            # after publishing: the adequacy test the estimate deferred, for the next ones
            self._feed.call('refresh')

    def _publish(self, est: InertiaEstimate, stamp: int) -> None:
        """Publish every output of one estimate, all stamped ``stamp`` [ns]; log a change
        of the status."""
        self._outputs.publish(est, stamp, self._admission.frame or '',
                              publish_partial=bool(self._cfg['publish_partial']),
                              omega=self._admission.last_omega,
                              marker_scale=float(self._cfg['marker_scale']))
        self._last_estimate = est
        if est.status != self._status:
            reason = est.diagnostics.get('reason') if est.status != 'ok' else ''
            self.get_logger().info(f'status {self._status or "start"} -> {est.status}'
                                   + (f': {reason}' if reason else ''))
            self._status = est.status

    def _problems(self, now: float) -> list[tuple[bytes, str]]:
        """Node-level conditions for the diagnostics: (level, message) each."""
        timeout = self._cfg['stream_timeout']
        act = self._actuators
        out = self._admission.problems(
            now, started=self._started, timeout=timeout,
            refused_limit=self._cfg['max_refused_fraction'],
            frame_hold=max(timeout, 2 * DIAGNOSTIC_PERIOD),
            joints_text='' if act is None else f'{act.file} ({", ".join(act.joints)})')
        if self._feed.core_error:
            out.append((DiagnosticStatus.ERROR, self._feed.core_error))
        return out

    def counts(self) -> dict[str, Any]:
        """Node-level counts and ages reported in the diagnostics (also used by tests)."""
        out = self._admission.counts(time.monotonic())
        out['resets'] = self._resets
        out['last_reset_reason'] = self._reset_reason or ''
        out['frame_id'] = self._admission.frame or ''
        out['update_ms'] = self._update_ms
        return out

    def force_update(self) -> None:
        """Publish the diagnostics now (the 1 Hz timer calls this; so may tests and tools).

        The status is named ``'<node name>: inertia estimate'`` with the node name as
        hardware_id (diagnostic_updater convention) and stamped with the node clock.
        """
        with self._lock:
            now = time.monotonic()
            result = None if self._last_estimate is None else self._last_estimate.to_dict()
            name = self.get_name()
            status = diagnostic_status(
                result, name=status_name(name, DIAGNOSTIC_TASK), hardware_id=name,
                extra=self.counts(), problems=self._problems(now))
            stamp = self.get_clock().now().nanoseconds
        self._pub_diag.publish(diagnostic_array([status], stamp))


def main(args: list[str] | None = None) -> None:
    """Run the node until Ctrl-C or shutdown (``ros2 run inertia_ros inertia_estimator``)."""
    run_node(InertiaEstimatorNode, NODE_NAME, args)


if __name__ == '__main__':
    main()
