"""``inertia_estimator``: the live inertia-tensor estimator node (ROS 2 Jazzy).

Subscribes the gyro stream (``imu``: sensor_msgs/Imu, or ``omega``: geometry_msgs/
Vector3Stamped by parameter) and the torque stream (``torque``: geometry_msgs/WrenchStamped,
or Vector3Stamped by parameter) with sensor-data QoS (best effort, volatile; history depth
``qos_depth`` so that a short stall of the executor drops nothing at 1 kHz).  Samples are
aligned by their header stamps inside the core (:mod:`inertia_ros.core.estimation`); this node
only converts messages, keeps counts and publishes:

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
:class:`inertia_ros.core.estimation.windowed.OnlineEstimator`.
"""
from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import InertiaStamped, QuaternionStamped, Vector3Stamped, WrenchStamped
from rcl_interfaces.msg import (
    FloatingPointRange,
    IntegerRange,
    ParameterDescriptor,
    ParameterType,
    SetParametersResult,
)
from rclpy.clock import Clock, ClockChange, JumpThreshold, TimeJump
from rclpy.clock_type import ClockType
from rclpy.duration import Duration
from rclpy.event_handler import PublisherEventCallbacks
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.subscription import Subscription
from sensor_msgs.msg import Imu
from std_srvs.srv import Trigger
from visualization_msgs.msg import MarkerArray

from inertia_ros.core.estimation.options import HOLDS, METHODS, TORQUE_BIAS
from inertia_ros.core.estimation.recursive import RecursiveEstimator
from inertia_ros.core.estimation.result import InertiaEstimate
from inertia_ros.core.estimation.windowed import ONLINE_METHODS, BatchWindow, OnlineEstimator
from inertia_ros.io import cdr_decode
from inertia_ros.nodes import messages
from inertia_ros.nodes._ros import (
    PolledGroup,
    latched_qos,
    polled_subscription,
    run_node,
    sensor_qos,
    take_raw,
)
from inertia_ros.nodes.diagnostics import (
    DIAGNOSTIC_PERIOD,
    diagnostic_array,
    diagnostic_status,
    status_name,
)
from inertia_ros.nodes.markers import inertia_markers

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


@dataclass(frozen=True)
class _Param:
    """One declared parameter: default, description and range (None: no range)."""

    default: Any
    description: str
    lo: float | None = None
    hi: float | None = None
    read_only: bool = False
    choices: tuple[str, ...] = ()


#: Every parameter of the node (config/inertia_estimator.yaml documents the same set).
PARAMETERS: dict[str, _Param] = {
    'omega_msg_type': _Param('imu', "gyro input: 'imu' (sensor_msgs/Imu on 'imu') or "
                             "'vector3' (geometry_msgs/Vector3Stamped on 'omega')",
                             read_only=True, choices=tuple(OMEGA_TYPES)),
    'torque_msg_type': _Param('wrench', "torque input on 'torque': 'wrench' (geometry_msgs/"
                              "WrenchStamped, torque part) or 'vector3' (Vector3Stamped) [N m]",
                              read_only=True, choices=tuple(TORQUE_TYPES)),
    'qos_depth': _Param(1000, 'history depth of the sensor-data subscriptions [messages]',
                        1, 100000, read_only=True),
    'poll_period': _Param(0.01, 'period at which queued input messages are taken and '
                          'decoded in one batch [s]', 0.0005, 1.0, read_only=True),
    'frame_id': _Param('', "frame the gyro and torque must be expressed in; '' adopts the "
                       'first gyro message\'s frame'),
    'method': _Param('recursive', "'recursive' (core RecursiveEstimator over all data or the "
                     "window) or 'batch' (core estimate() re-solved over the sliding window)",
                     choices=ONLINE_METHODS),
    'batch_method': _Param('integral', "core estimator of the 'batch' method: 'integral' "
                           "(fast), 'ml' (maximum likelihood, at the Cramer-Rao bound, ~5x the "
                           "time), 'auto' or another name of the core's METHODS",
                           choices=METHODS),
    'model': _Param('full', "tensor parameters: 'full' (6), 'diagonal' (3), 'axisymmetric' "
                    "(2, needs symmetry_axis) or 'auto' (model selection in the core)"),
    'symmetry_axis': _Param('', "symmetry axis for model 'axisymmetric': 'x', 'y' or 'z' "
                            "('' = none)", choices=('', 'x', 'y', 'z')),
    'torque_bias': _Param('auto', "estimate a constant unmeasured disturbance torque [N m]: "
                          "'off', 'on' or 'auto' (kept when significant; the recursive "
                          "method re-tests it about once a second)",
                          choices=TORQUE_BIAS),
    'forgetting': _Param(1.0, 'recursive forgetting factor per gyro sample; 1 = none '
                         '[dimensionless]', 0.5, 1.0),
    'window': _Param(0.0, 'recursive: memory time constant, weights decay as '
                     'exp(-age/window) [s], 0 = no decay; batch: sliding-window length [s], '
                     '0 = 30 s', 0.0, 86400.0),
    'hold': _Param('zoh', "torque between samples: 'zoh' (held) or 'linear'", choices=HOLDS),
    'publish_rate': _Param(10.0, 'maximum estimate/publish rate [Hz]', 0.01, 1000.0),
    'publish_partial': _Param(False, 'also publish ~/inertia when partially_identifiable '
                              '(undetermined elements NaN)'),
    'stream_timeout': _Param(1.0, 'warn when a stream is silent this long [s]', 0.01, 3600.0),
    'clock_jump_threshold': _Param(0.5, 'reset when input stamps jump back more than this [s]',
                                   0.0, 3600.0),
    'marker_scale': _Param(0.5, 'display size of the markers (longest ellipsoid semi-axis) [m]',
                           0.001, 100.0),
}

BATCH_DEFAULT_WINDOW = 30.0  # s, batch re-solve when window = 0


def _descriptor(name: str, p: _Param) -> ParameterDescriptor:
    """The ParameterDescriptor of one entry of :data:`PARAMETERS` (range, constraint)."""
    desc = ParameterDescriptor(name=name, description=p.description, read_only=p.read_only)
    if p.choices:
        desc.additional_constraints = 'one of: ' + ', '.join(p.choices)
    if p.lo is None or isinstance(p.default, bool):
        return desc
    if isinstance(p.default, int):
        desc.type = ParameterType.PARAMETER_INTEGER
        desc.integer_range = [IntegerRange(from_value=int(p.lo), to_value=int(p.hi), step=0)]
    else:
        desc.type = ParameterType.PARAMETER_DOUBLE
        desc.floating_point_range = [FloatingPointRange(from_value=float(p.lo),
                                                        to_value=float(p.hi), step=0.0)]
    return desc


def make_estimator(cfg: dict[str, Any]) -> Callable[[], OnlineEstimator]:
    """Return a factory for the online estimator described by ``cfg`` (validated now).

    Parameters
    ----------
    cfg : dict
        The node's parameter values (``method``, ``batch_method``, ``model``,
        ``symmetry_axis``, ``torque_bias``, ``forgetting``, ``window`` [s], ``hold``,
        ``publish_rate`` [Hz]).

    Returns
    -------
    callable
        ``() -> OnlineEstimator``: a RecursiveEstimator (``method='recursive'``) or a
        BatchWindow (``'batch'``).

    Raises
    ------
    ValueError
        From the core, naming the offending setting.
    """
    axis = cfg['symmetry_axis'] or None
    if cfg['method'] == 'recursive':
        # model selection ('auto') re-run about once a second, its choice reused in between:
        # the per-update cost (and so the latency) stays that of one fit
        kwargs = dict(model=cfg['model'], torque_bias=cfg['torque_bias'],
                      forgetting=float(cfg['forgetting']),
                      window=float(cfg['window']) or None, hold=cfg['hold'],
                      symmetry_axis=axis, reselect_every=_reselect_every(cfg))
        RecursiveEstimator(**kwargs)  # validates
        return lambda: RecursiveEstimator(**kwargs)
    window = float(cfg['window']) or BATCH_DEFAULT_WINDOW
    options = dict(method=cfg['batch_method'], model=cfg['model'],
                   torque_bias=cfg['torque_bias'], hold=cfg['hold'], symmetry_axis=axis)
    BatchWindow(window, **options)  # validates
    return lambda: BatchWindow(window, **options)


def _reselect_every(cfg: dict[str, Any]) -> int:
    """Model-selection period of the recursive estimator [updates]: about once a second."""
    return max(1, round(float(cfg['publish_rate'])))


@dataclass
class _Stream:
    """Per-stream bookkeeping: input subscription, counts, newest stamp, pending samples."""

    name: str
    msg_type: str
    field_name: str
    sub: Subscription | None = None
    received: int = 0
    malformed: int = 0
    nan_dropped: int = 0
    out_of_order: int = 0
    refused: int = 0
    before_gyro: int = 0
    last_ns: int | None = None
    last_rx: float | None = None  # steady clock [s]
    t_ns: list[np.ndarray] = field(default_factory=list)
    values: list[np.ndarray] = field(default_factory=list)

    @property
    def topic(self) -> str:
        """The resolved input topic."""
        return self.sub.topic_name if self.sub is not None else ''


class InertiaEstimatorNode(Node):
    """ROS 2 wrapper around the core's online inertia estimators (see the module docstring)."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(NODE_NAME, **kwargs)
        for name, p in PARAMETERS.items():
            self.declare_parameter(name, p.default, _descriptor(name, p))
        cfg = {name: self.get_parameter(name).value for name in PARAMETERS}
        problem = self._validate(cfg)
        if problem:
            raise ValueError(problem)
        self._cfg = cfg
        self._lock = threading.RLock()
        self._factory = make_estimator(cfg)
        self._estimator: OnlineEstimator = self._factory()
        self._epoch_ns: int | None = None
        self._frame: str | None = cfg['frame_id'] or None
        self._resets = 0
        self._last_update = -math.inf
        self._last_estimate: InertiaEstimate | None = None
        self._last_omega: np.ndarray | None = None
        self._frame_problem: tuple[float, str] | None = None
        self._reset_reason: str | None = None
        self._update_ms = 0.0
        self._core_error: str | None = None
        self._started = time.monotonic()
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self._make_inputs(cfg)
        self._make_outputs()
        self.get_logger().info(
            f'listening on {self._gyro.topic} ({OMEGA_TYPES[cfg["omega_msg_type"]][0].__name__})'
            f' and {self._torque.topic} ({TORQUE_TYPES[cfg["torque_msg_type"]][0].__name__}); '
            f'method={cfg["method"]}, model={cfg["model"]}, torque_bias={cfg["torque_bias"]}')

    def _make_inputs(self, cfg: dict[str, Any]) -> None:
        """The two polled input subscriptions and the steady-clock poll timer."""
        om_type, om_topic, om_cdr, om_field = OMEGA_TYPES[cfg['omega_msg_type']]
        tq_type, tq_topic, tq_cdr, tq_field = TORQUE_TYPES[cfg['torque_msg_type']]
        qos = sensor_qos(int(cfg['qos_depth']))
        polled = PolledGroup()
        self._gyro = _Stream('gyro', om_cdr, om_field,
                             sub=polled_subscription(self, om_type, om_topic, qos, polled))
        self._torque = _Stream('torque', tq_cdr, tq_field,
                               sub=polled_subscription(self, tq_type, tq_topic, qos, polled))
        # Polling and the diagnostics run on the steady clock: with use_sim_time they must
        # not stop when /clock pauses, nor speed up with a fast bag.
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._poll_timer = self.create_timer(float(cfg['poll_period']), self._on_poll,
                                             clock=self._steady)

    def _make_outputs(self) -> None:
        """Publishers, the reset service, the diagnostics timer and the clock-jump handler."""
        # No QoS-event handlers on the outputs: each would be one more entity in every
        # executor wait-set, i.e. CPU at every poll.
        quiet = {'event_callbacks': PublisherEventCallbacks(use_default_callbacks=False)}
        self._pub_inertia = self.create_publisher(InertiaStamped, '~/inertia', latched_qos(),
                                                  **quiet)
        self._pub_moments = self.create_publisher(Vector3Stamped, '~/principal_moments', 10,
                                                  **quiet)
        self._pub_axes = self.create_publisher(QuaternionStamped, '~/principal_axes', 10,
                                               **quiet)
        self._pub_diag = self.create_publisher(DiagnosticArray, '/diagnostics', 10, **quiet)
        self._pub_markers = self.create_publisher(MarkerArray, '~/markers', 10, **quiet)
        self._srv_reset = self.create_service(Trigger, '~/reset', self._on_reset)
        self._diag_timer = self.create_timer(DIAGNOSTIC_PERIOD, self.force_update,
                                             clock=self._steady)
        self._jump_handle = self.get_clock().create_jump_callback(
            JumpThreshold(min_forward=None, min_backward=Duration(nanoseconds=-1_000_000),
                          on_clock_change=True),
            post_callback=self._on_clock_jump)

    # ------------------------------------------------------------------ parameters
    @staticmethod
    def _validate(cfg: dict[str, Any]) -> str:
        """Return '' when the configuration is valid, else a message naming the problem."""
        for name, p in PARAMETERS.items():
            v = cfg[name]
            if p.choices and v not in p.choices:
                return f'{name} must be one of {list(p.choices)}, got {v!r}'
            if p.lo is not None and not (p.lo <= v <= p.hi):
                return f'{name} must be in [{p.lo}, {p.hi}], got {v!r}'
        try:
            make_estimator(cfg)
        except ValueError as exc:
            return f'rejected by the estimator: {exc}'
        return ''

    def _on_set_parameters(self, params: list[Parameter]) -> SetParametersResult:
        """Validate a parameter change; on success rebuild the estimator (a reset)."""
        cfg = dict(self._cfg)
        for p in params:
            if p.name in PARAMETERS:
                cfg[p.name] = p.value
        problem = self._validate(cfg)
        if problem:
            return SetParametersResult(successful=False, reason=problem)
        with self._lock:
            rebuild = any(cfg[k] != self._cfg[k] for k in
                          ('method', 'batch_method', 'model', 'symmetry_axis', 'torque_bias',
                           'forgetting', 'window', 'hold'))
            if cfg['frame_id'] != self._cfg['frame_id']:
                self._frame = cfg['frame_id'] or None
                rebuild = True
            rate_changed = cfg['publish_rate'] != self._cfg['publish_rate']
            self._cfg = cfg
            if rebuild:
                self._factory = make_estimator(cfg)
                self._reset('parameters changed')
            elif rate_changed:
                # the model-selection period follows the publish rate; the estimate is kept
                self._factory = make_estimator(cfg)
                if isinstance(self._estimator, RecursiveEstimator):
                    self._estimator.reselect_every = _reselect_every(cfg)
        return SetParametersResult(successful=True)

    # ------------------------------------------------------------------ input
    def _on_poll(self) -> None:
        """Take every queued input message, check and queue the samples, maybe update."""
        for s in (self._gyro, self._torque):
            payloads = take_raw(s.sub)
            if payloads:
                self._accept(s, payloads)
        self._maybe_update()

    def _accept(self, s: _Stream, payloads: list[bytes]) -> None:
        """Decode a batch of serialised messages and queue the usable samples.

        Malformed payloads, NaN/Inf samples, samples from another frame and stamps older
        than the newest one are dropped and counted; a backward jump of the stamps larger
        than ``clock_jump_threshold`` resets the estimator and starts over at that sample.
        """
        now = time.monotonic()
        batch = cdr_decode.decode_payloads(s.msg_type, payloads, fields=(s.field_name,))
        with self._lock:
            s.received += len(payloads)
            s.last_rx = now
            ok = batch.ok.copy()
            s.malformed += int(np.count_nonzero(~ok))
            if self._frame is None:
                if s is not self._gyro:
                    # The estimation frame is the gyro's: torque before the first gyro
                    # message cannot be checked yet (and covers no gyro sample).
                    s.before_gyro += int(np.count_nonzero(ok))
                    return
                if ok.any():
                    self._frame = batch.frame_ids[batch.frame_index[np.argmax(ok)]]
                    self.get_logger().info(f'estimating in frame {self._frame!r} '
                                           '(first gyro message)')
            for k, frame in enumerate(batch.frame_ids):
                if frame != self._frame:
                    bad = ok & (batch.frame_index == k)
                    n_bad = int(np.count_nonzero(bad))
                    if n_bad:
                        s.refused += n_bad
                        ok &= ~bad
                        text = (f'{s.name} frame {frame!r} differs from the estimation frame '
                                f'{self._frame!r}: samples refused')
                        self._frame_problem = (now, text)
                        self.get_logger().warning(text, throttle_duration_sec=5.0)
            values = batch.fields[s.field_name]
            finite = np.all(np.isfinite(values), axis=1)
            s.nan_dropped += int(np.count_nonzero(ok & ~finite))
            ok &= finite
            t_ns = batch.stamp_ns[ok]
            values = values[ok]
            if t_ns.size == 0:
                return
            # Backward jumps against the newest stamp seen so far (within and across batches).
            start = -np.inf if s.last_ns is None else s.last_ns
            prev_max = np.maximum.accumulate(np.concatenate([[start], t_ns[:-1]]))
            jump = np.flatnonzero(prev_max - t_ns > self._cfg['clock_jump_threshold'] * 1e9)
            if jump.size:
                j = int(jump[-1])
                self._reset(f'{s.name} stamps jumped back '
                            f'{(prev_max[j] - t_ns[j]) * 1e-9:.3f} s')
                t_ns, values = t_ns[j:], values[j:]
                prev_max = np.maximum.accumulate(np.concatenate([[-np.inf], t_ns[:-1]]))
            fresh = t_ns > prev_max
            s.out_of_order += int(np.count_nonzero(~fresh))
            t_ns, values = t_ns[fresh], values[fresh]
            if t_ns.size == 0:
                return
            if self._epoch_ns is None:
                self._epoch_ns = int(t_ns[0])
            s.last_ns = int(t_ns[-1])
            s.t_ns.append(t_ns)
            s.values.append(values)
            if s is self._gyro:
                self._last_omega = values[-1]

    def _flush(self, s: _Stream, add: Callable[[np.ndarray, np.ndarray], None]) -> None:
        if not s.t_ns:
            return
        t = (np.concatenate(s.t_ns) - self._epoch_ns) * 1e-9
        add(t, np.concatenate(s.values))
        s.t_ns.clear()
        s.values.clear()

    # ------------------------------------------------------------------ reset / clock
    def _reset(self, reason: str) -> None:
        """Forget every sample (estimator, pending buffers, epoch); counts are kept."""
        with self._lock:
            self._estimator = self._factory()
            for s in (self._gyro, self._torque):
                s.t_ns.clear()
                s.values.clear()
                s.last_ns = None
            self._epoch_ns = None
            self._last_result = None
            self._resets += 1
            self._reset_reason = reason
        self.get_logger().info(f'estimator reset: {reason}')

    def _on_reset(self, request: Trigger.Request, response: Trigger.Response
                  ) -> Trigger.Response:
        self._reset('~/reset service')
        response.success = True
        response.message = f'estimator reset ({self._resets} resets so far)'
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

    def _flush(self, s: _Stream, add: Callable[[np.ndarray, np.ndarray], None]) -> None:
        """Hand the pending samples of one stream to the estimator ([s] since the epoch)."""
        if not s.t_ns:
            return
        t = (np.concatenate(s.t_ns) - self._epoch_ns) * 1e-9
        add(t, np.concatenate(s.values))
        s.t_ns.clear()
        s.values.clear()

    # ------------------------------------------------------------------ reset / clock
    def _reset(self, reason: str) -> None:
        """Forget every sample (estimator, pending buffers, epoch); counts are kept."""
        with self._lock:
            self._estimator = self._factory()
            for s in (self._gyro, self._torque):
                s.t_ns.clear()
                s.values.clear()
                s.last_ns = None
            self._epoch_ns = None
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
        """Update when samples are pending and the publish period has elapsed."""
        if not (self._gyro.t_ns or self._torque.t_ns):
            return
        now = time.monotonic()
        if now - self._last_update >= 1.0 / self._cfg['publish_rate']:
            self._update(now)

    def _update(self, now: float) -> None:
        """Hand buffered samples to the core, estimate, publish everything."""
        with self._lock:
            self._last_update = now
            if self._epoch_ns is None:
                return
            self._flush(self._gyro, self._estimator.add_gyro)
            self._flush(self._torque, self._estimator.add_torque)
            est = self._estimate()
            self._update_ms = (time.monotonic() - now) * 1e3
            stamp = max(x for x in (self._gyro.last_ns, self._torque.last_ns) if x is not None)
            self._publish(est, stamp)

    def _estimate(self) -> InertiaEstimate:
        """The core's estimate; a core error becomes ``insufficient_data`` with its reason.

        ValueError from the core means the data cannot give an estimate yet (too few
        samples, no overlap of the streams); anything else is a bug worth an ERROR
        diagnostic, but never a reason to stop the node.
        """
        try:
            est = self._estimator.estimate()
            self._core_error = None
            return est
        except ValueError as exc:
            self._core_error = None
            reason = str(exc)
        except Exception as exc:  # a core bug must not take the node down
            reason = f'estimator error: {type(exc).__name__}: {exc}'
            self._core_error = reason
            self.get_logger().error(reason, throttle_duration_sec=5.0)
        return InertiaEstimate('insufficient_data', method=self._cfg['method'],
                               diagnostics={'reason': reason})

    def _publish(self, est: InertiaEstimate, stamp: int) -> None:
        """Publish every output of one estimate, all stamped ``stamp`` [ns]."""
        frame = self._frame or ''
        status = est.status
        valid = status == 'ok' or (status == 'partially_identifiable'
                                   and self._cfg['publish_partial'])
        if valid and est.inertia is not None:  # the main output first: lowest latency
            self._pub_inertia.publish(messages.inertia_stamped(est.inertia, stamp, frame))
        self._last_estimate = est
        have_axes = est.principal_moments is not None and est.principal_axes is not None \
            and np.all(np.isfinite(est.principal_moments)) \
            and np.all(np.isfinite(est.principal_axes))
        if have_axes:
            self._pub_moments.publish(
                messages.principal_moments_msg(est.principal_moments, stamp, frame))
            self._pub_axes.publish(messages.principal_axes_msg(est.principal_axes, stamp, frame))
        self._pub_markers.publish(inertia_markers(
            stamp, frame, inertia=est.inertia if valid else None,
            moments=est.principal_moments if have_axes else None,
            axes=est.principal_axes if have_axes else None,
            omega=self._last_omega, scale=float(self._cfg['marker_scale']), label=status))

    def _problems(self, now: float) -> list[tuple[bytes, str]]:
        """Node-level conditions for the diagnostics: (level, message) each."""
        out: list[tuple[bytes, str]] = []
        timeout = self._cfg['stream_timeout']
        for s in (self._gyro, self._torque):
            if s.last_rx is None:
                if now - self._started > timeout:
                    out.append((DiagnosticStatus.WARN, f'no {s.name} message on {s.topic} yet'))
            elif now - s.last_rx > timeout:
                out.append((DiagnosticStatus.WARN, f'{s.name} stream on {s.topic} silent for '
                            f'{now - s.last_rx:.1f} s (timeout {timeout:g} s)'))
        if self._frame_problem and now - self._frame_problem[0] <= max(timeout,
                                                                   2 * DIAGNOSTIC_PERIOD):
            out.append((DiagnosticStatus.ERROR, self._frame_problem[1]))
        if self._core_error:
            out.append((DiagnosticStatus.ERROR, self._core_error))
        return out

    def counts(self) -> dict[str, Any]:
        """Node-level counts and ages reported in the diagnostics (also used by tests)."""
        now = time.monotonic()
        out: dict[str, Any] = {}
        for s in (self._gyro, self._torque):
            out[f'{s.name}_received'] = s.received
            out[f'{s.name}_malformed'] = s.malformed
            out[f'{s.name}_nan_dropped'] = s.nan_dropped
            out[f'{s.name}_out_of_order_dropped'] = s.out_of_order
            out[f'{s.name}_frame_refused'] = s.refused
        out['torque_before_gyro_dropped'] = self._torque.before_gyro
        for s in (self._gyro, self._torque):
            out[f'{s.name}_age_s'] = None if s.last_rx is None else now - s.last_rx
        out['resets'] = self._resets
        out['last_reset_reason'] = self._reset_reason or ''
        out['frame_id'] = self._frame or ''
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
