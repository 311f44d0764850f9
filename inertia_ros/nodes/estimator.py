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
:class:`inertia_ros.core.estimation.windowed.OnlineEstimator`.
"""
from __future__ import annotations

import math
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import InertiaStamped, QuaternionStamped, Vector3Stamped, WrenchStamped
from rcl_interfaces.msg import (
    SetParametersResult,
)
from rclpy.clock import Clock, ClockChange, JumpThreshold, TimeJump
from rclpy.clock_type import ClockType
from rclpy.duration import Duration
from rclpy.event_handler import PublisherEventCallbacks
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.subscription import Subscription
from sensor_msgs.msg import Imu, JointState
from std_msgs.msg import Float64MultiArray
from std_srvs.srv import Trigger
from visualization_msgs.msg import MarkerArray

from inertia_ros.core.estimation.recursive import RecursiveEstimator
from inertia_ros.core.estimation.recursive_momentum import MomentumRecursiveEstimator
from inertia_ros.core.estimation.result import InertiaEstimate
from inertia_ros.core.estimation.tracking import TrackingEstimator
from inertia_ros.core.estimation.windowed import BatchWindow, OnlineEstimator
from inertia_ros.io import cdr_decode
from inertia_ros.nodes import messages, params
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
from inertia_ros.nodes.params import ParamSpec

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

BATCH_DEFAULT_WINDOW = 30.0  # s, batch re-solve when window = 0
TRACKING_DEFAULT_WINDOW = 10.0  # s, tracking memory when window = 0
#: Consecutive samples that confirm a jump of the stamps (else the jumped ones are refused).
STAMP_CONFIRM = 5
#: Smallest forward stamp jump held for confirmation [ns] (clock_jump_threshold if larger).
FORWARD_JUMP_NS = 1_000_000_000
#: Time over which the fraction of refused samples is measured [s].
REFUSED_WINDOW = 1.0
#: Fewest samples over REFUSED_WINDOW for the refused fraction to count.
REFUSED_MIN_SAMPLES = 10


def make_estimator(cfg: dict[str, Any], actuators: Any = None
                   ) -> Callable[[], OnlineEstimator]:
    """Return a factory for the online estimator described by ``cfg`` (validated now).

    Parameters
    ----------
    cfg : dict
        The node's parameter values (``method``, ``batch_method``, ``model``,
        ``symmetry_axis``, ``torque_bias``, ``forgetting``, ``window`` [s], ``hold``,
        ``publish_rate`` [Hz], ``wheels_file``, ``rotors_file``, ``torque_topic``).
    actuators : inertia_ros.io.rotors.ActuatorInput, optional
        Wheels or rotors on ``joint_states``: a
        :class:`~inertia_ros.core.estimation.recursive_momentum.MomentumRecursiveEstimator`
        with their uncertain inputs (another torque only when ``torque_topic`` is not 'none').

    Returns
    -------
    callable
        ``() -> OnlineEstimator``: a RecursiveEstimator (``method='recursive'``), a
        TrackingEstimator (``'tracking'``: memory ``window`` or 10 s) or a BatchWindow
        (``'batch'``).

    Raises
    ------
    ValueError
        From the core, naming the offending setting.
    """
    axis = cfg['symmetry_axis'] or None
    if (cfg.get('wheels_file') or cfg.get('rotors_file')) and cfg['method'] != 'recursive':
        raise ValueError("wheels_file / rotors_file need method 'recursive'")
    if cfg['method'] == 'recursive':
        # model selection ('auto') re-run about once a second, its choice reused in between:
        # the per-update cost (and so the latency) stays that of one fit
        kwargs = dict(model=cfg['model'], torque_bias=cfg['torque_bias'],
                      forgetting=float(cfg['forgetting']),
                      window=float(cfg['window']) or None, hold=cfg['hold'],
                      symmetry_axis=axis, reselect_every=_reselect_every(cfg),
                      torque_scale_std=float(cfg['torque_scale_std']),
                      gyro_scale_std=float(cfg['gyro_scale_std']),
                      # the once-a-second adequacy test runs after publishing (refresh()),
                      # not between the newest input and the estimate
                      defer_adequacy=True)
        RecursiveEstimator(**kwargs)  # validates
        if actuators is not None:
            names = actuators.names
            other = cfg['torque_topic'].strip().lower() != 'none'
            return lambda: MomentumRecursiveEstimator(names=names, other_torque=other, **kwargs)
        return lambda: RecursiveEstimator(**kwargs)
    if cfg['method'] == 'tracking' and cfg['torque_topic'].strip().lower() == 'none':
        return torque_free_estimator(cfg)
    if cfg['method'] == 'tracking':
        kwargs = dict(window=float(cfg['window']) or TRACKING_DEFAULT_WINDOW,
                      model=cfg['model'], torque_bias=cfg['torque_bias'], hold=cfg['hold'],
                      symmetry_axis=axis, torque_scale_std=float(cfg['torque_scale_std']),
                      gyro_scale_std=float(cfg['gyro_scale_std']))
        TrackingEstimator(**kwargs)  # validates
        return lambda: TrackingEstimator(**kwargs)
    window = float(cfg['window']) or BATCH_DEFAULT_WINDOW
    options = dict(method=cfg['batch_method'], model=cfg['model'],
                   torque_bias=cfg['torque_bias'], hold=cfg['hold'], symmetry_axis=axis,
                   torque_scale_std=float(cfg['torque_scale_std']),
                   gyro_scale_std=float(cfg['gyro_scale_std']))
    BatchWindow(window, **options)  # validates
    return lambda: BatchWindow(window, **options)


def torque_free_estimator(cfg: dict[str, Any]) -> Callable[[], OnlineEstimator]:
    """The factory for torque-free data: ``make_estimator``'s, but the recursive estimator
    (memory ``window`` or 10 s) for ``method='tracking'``, whose Kalman filter needs the
    torque for the scale (the recursive one gives the ratios and axes, ``scale_unobservable``).
    """
    if cfg['method'] != 'tracking':
        return make_estimator(cfg)
    return make_estimator(dict(cfg, method='recursive',
                               window=float(cfg['window']) or TRACKING_DEFAULT_WINDOW))


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
    bad_stamp: int = 0
    before_gyro: int = 0
    last_ns: int | None = None
    last_rx: float | None = None  # steady clock [s]
    t_ns: list[np.ndarray] = field(default_factory=list)
    values: list[np.ndarray] = field(default_factory=list)
    #: samples whose stamps jumped (kept until confirmed or refused): (t [ns], value (3,))
    pending: list[tuple[int, np.ndarray]] = field(default_factory=list)
    #: per batch over the last second: (steady time [s], received, refused)
    recent: deque[tuple[float, int, int]] = field(default_factory=deque)

    @property
    def topic(self) -> str:
        """The resolved input topic ('' without a subscription)."""
        return self.sub.topic_name if self.sub is not None else ''

    @property
    def refused_total(self) -> int:
        """Samples refused so far: malformed, NaN/Inf, wrong frame, invalid stamp."""
        return self.malformed + self.nan_dropped + self.refused + self.bad_stamp

    def refused_fraction(self, now: float) -> tuple[float, int]:
        """Fraction of the samples received over the last :data:`REFUSED_WINDOW` s that were
        refused, and how many were received."""
        while self.recent and now - self.recent[0][0] > REFUSED_WINDOW:
            self.recent.popleft()
        n = sum(r[1] for r in self.recent)
        bad = sum(r[2] for r in self.recent)
        return (bad / n if n else 0.0), n


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
        self._torque_free = cfg['torque_topic'].strip().lower() == 'none'
        self._make_inputs(cfg)
        self._factory = make_estimator(cfg, self._actuators)
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
        self._fed = False                     # samples handed over ahead of the next update
        self._merged = False                  # (and merged: once per update, _maybe_update)
        self._core_error: str | None = None
        self._status: str | None = None       # last published status (logged on change)
        #: torque-free estimator fed while no torque message has arrived (zero torque)
        self._shadow: OnlineEstimator | None = None
        self._started = time.monotonic()
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self._make_outputs()
        torque = ('no torque stream (torque_topic none): torque-free estimation'
                  if self._torque_free else
                  f'{self._torque.topic} ({TORQUE_TYPES[cfg["torque_msg_type"]][0].__name__})')
        if self._joints is not None:
            torque += (f' and {self._joints.topic} (JointState: {self._actuators.kind} of '
                       f'{self._actuators.file})')
        self.get_logger().info(
            f'listening on {self._gyro.topic} ({OMEGA_TYPES[cfg["omega_msg_type"]][0].__name__})'
            f' and {torque}; '
            f'method={cfg["method"]}, model={cfg["model"]}, torque_bias={cfg["torque_bias"]}')

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
        """The polled input subscriptions and the steady-clock poll timer."""
        om_type, om_topic, om_cdr, om_field = OMEGA_TYPES[cfg['omega_msg_type']]
        tq_type, tq_topic, tq_cdr, tq_field = TORQUE_TYPES[cfg['torque_msg_type']]
        qos = sensor_qos(int(cfg['qos_depth']))
        polled = PolledGroup()
        self._gyro = _Stream('gyro', om_cdr, om_field,
                             sub=polled_subscription(self, om_type, om_topic, qos, polled))
        self._torque = _Stream('torque', tq_cdr, tq_field, sub=None if self._torque_free else
                               polled_subscription(self, tq_type, cfg['torque_topic'] or
                                                   tq_topic, qos, polled))
        self._joints = None if self._actuators is None else _Stream(
            'joints', 'sensor_msgs/msg/JointState', 'velocity',
            sub=polled_subscription(self, JointState, 'joint_states', qos, polled))
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
        self._pub_cov = self.create_publisher(Float64MultiArray, '~/inertia_covariance', 10,
                                              **quiet)
        self._pub_moments_std = self.create_publisher(Vector3Stamped, '~/principal_moments_std',
                                                      10, **quiet)
        self._pub_ratios = self.create_publisher(Vector3Stamped, '~/principal_ratios', 10,
                                                 **quiet)
        self._pub_ratios_std = self.create_publisher(Vector3Stamped, '~/principal_ratios_std',
                                                     10, **quiet)
        self._pub_diag = self.create_publisher(DiagnosticArray, '/diagnostics', 10, **quiet)
        self._pub_markers = self.create_publisher(MarkerArray, '~/markers', 10, **quiet)
        self._srv_reset = self.create_service(Trigger, '~/reset', self._on_reset)
        self._srv_urdf = self.create_service(Trigger, '~/urdf', self._on_urdf)
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
            rebuild = any(cfg[k] != self._cfg[k] for k in
                          ('method', 'batch_method', 'model', 'symmetry_axis', 'torque_bias',
                           'forgetting', 'window', 'hold', 'torque_scale_std',
                           'gyro_scale_std'))
            if cfg['frame_id'] != self._cfg['frame_id']:
                self._frame = cfg['frame_id'] or None
                rebuild = True
            rate_changed = cfg['publish_rate'] != self._cfg['publish_rate']
            self._cfg = cfg
            if rebuild:
                self._factory = make_estimator(cfg, self._actuators)
                self._reset('parameters changed')
            elif rate_changed:
                # the model-selection period follows the publish rate; the estimate is kept
                self._factory = make_estimator(cfg, self._actuators)
                if isinstance(self._estimator, RecursiveEstimator):
                    self._estimator.reselect_every = _reselect_every(cfg)
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

    def _incremental(self) -> bool:
        """Whether samples are handed over and merged ahead of the update (see
        :meth:`_maybe_update`).

        Only the plain recursive estimator: its statistics do not depend on how the samples
        were cut into blocks (the tracking and momentum estimators get them at the update,
        as before).
        """
        return type(self._estimator) is RecursiveEstimator

    def _accept_joints(self, payloads: list[bytes]) -> None:
        """Decode JointState messages and queue the speeds of the file's joints, in order.

        Messages without every joint of the file (other joints on the same topic) are
        skipped; malformed ones, NaN/Inf speeds and zero stamps are refused and counted;
        stamps not after the newest are dropped as out of order.  Before the first gyro
        message (no estimation frame yet) samples are dropped, as torque samples are.
        """
        from inertia_ros.io.joint_state import decode_joint_state

        s = self._joints
        joints = self._actuators.joints
        now = time.monotonic()
        refused = s.refused_total
        stamps: list[int] = []
        rows: list[np.ndarray] = []
        for data in payloads:
            try:
                st, names, _pos, vel = decode_joint_state(data)
            except ValueError:
                s.malformed += 1
                continue
            idx = {n: i for i, n in enumerate(names)}
            if len(vel) != len(names) or any(j not in idx for j in joints):
                continue
            v = vel[[idx[j] for j in joints]]
            if not np.all(np.isfinite(v)):
                s.nan_dropped += 1
            elif st <= 0:
                s.bad_stamp += 1
            else:
                stamps.append(st)
                rows.append(v)
        with self._lock:
            s.received += len(payloads)
            s.last_rx = now
            s.recent.append((now, len(payloads), s.refused_total - refused))
            if self._frame is None or self._epoch_ns is None:
                s.before_gyro += len(stamps)
                return
            for st, v in zip(stamps, rows, strict=True):
                if s.last_ns is not None and st <= s.last_ns:
                    s.out_of_order += 1
                    continue
                s.last_ns = st
                s.t_ns.append(np.array([st], dtype=np.int64))
                s.values.append(v[None, :])

    def _add_joints(self, t: np.ndarray, speed: np.ndarray) -> None:
        """Hand JointState speeds to the estimator as its momentum input; samples the
        estimator refuses (stamps of an older timeline after a reset) are counted."""
        try:
            self._estimator.add_momentum(self._actuators.block(t, speed))
        except ValueError:
            self._joints.out_of_order += len(t)

    def _accept(self, s: _Stream, payloads: list[bytes]) -> None:
        """Decode a batch of serialised messages and queue the usable samples.

        Malformed payloads, NaN/Inf samples, samples from another frame and invalid stamps
        (zero, or further than ``clock_jump_threshold`` from the newest stamp without
        :data:`STAMP_CONFIRM` consecutive samples confirming the jump) are refused and
        counted; stamps older than the newest one are dropped as out of order.  A confirmed
        backward jump (bag loop, simulator restart) resets the estimator and starts over at
        that sample; a confirmed forward jump is a gap.
        """
        now = time.monotonic()
        batch = cdr_decode.decode_payloads(s.msg_type, payloads, fields=(s.field_name,))
        with self._lock:
            refused_before = s.refused_total
            try:
                self._accept_locked(s, batch, now)
            finally:
                s.received += len(payloads)
                s.last_rx = now
                s.recent.append((now, len(payloads), s.refused_total - refused_before))

    def _accept_locked(self, s: _Stream, batch: Any, now: float) -> None:
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
        thr = int(self._cfg['clock_jump_threshold'] * 1e9)
        fwd = max(thr, FORWARD_JUMP_NS)
        start = -np.inf if s.last_ns is None else s.last_ns
        prev_max = np.maximum.accumulate(np.concatenate([[start], t_ns[:-1]]))
        ref = np.maximum(prev_max, t_ns[0]) if s.last_ns is None else prev_max
        suspect = (t_ns <= 0) | (ref - t_ns > thr) | (t_ns - ref > fwd)
        if s.pending or suspect.any():
            t_ns, values = self._check_stamps(s, t_ns, values, thr, fwd)
            if t_ns.size == 0:
                return
            prev_max = np.maximum.accumulate(np.concatenate(
                [[-np.inf if s.last_ns is None else s.last_ns], t_ns[:-1]]))
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

    def _check_stamps(self, s: _Stream, t_ns: np.ndarray, values: np.ndarray, thr: int,
                      fwd: int) -> tuple[np.ndarray, np.ndarray]:
        """The slow path of :meth:`_accept_locked`: samples with invalid or jumping stamps.

        Returns the samples to go on with (in order; out-of-order ones are dropped by the
        caller).  A zero stamp is always refused.  A stamp more than ``thr`` [ns] behind or
        ``fwd`` [ns] ahead of the newest accepted one is held in ``s.pending``; when
        :data:`STAMP_CONFIRM` consecutive held samples agree (increasing, no jump between
        them), the jump is real: backward resets the estimator, forward is a gap, and the
        held samples are used.  A sample that fits the old timeline again refuses the held
        ones (a glitch), counted in ``bad_stamp``.
        """
        keep_t: list[int] = []
        keep_v: list[np.ndarray] = []
        newest = s.last_ns
        for t, v in zip(t_ns.tolist(), values, strict=True):
            if t <= 0:
                s.bad_stamp += 1
                continue
            if newest is None and s.pending:      # reset meanwhile: the held samples lead
                newest = self._take_pending(s, keep_t, keep_v)
            if newest is None or -thr <= t - newest <= fwd:
                if s.pending:                     # the old timeline goes on: a glitch
                    self._refuse_pending(s)
                keep_t.append(t)
                keep_v.append(v)
                newest = t if newest is None else max(newest, t)
                continue
            if s.pending and not (0 < t - s.pending[-1][0] <= fwd):
                self._refuse_pending(s)           # not even consistent with the held ones
            s.pending.append((t, v))
            if len(s.pending) < STAMP_CONFIRM:
                continue
            jump = (s.pending[0][0] - newest) * 1e-9
            if jump < 0:
                self._reset(f'{s.name} stamps jumped back {-jump:.3f} s')
                keep_t.clear()
                keep_v.clear()
            else:
                self.get_logger().info(f'{s.name} stamps jumped ahead {jump:.3f} s: a gap')
            newest = self._take_pending(s, keep_t, keep_v)
        if not keep_t:
            return t_ns[:0], values[:0]
        return np.asarray(keep_t, dtype=np.int64), np.asarray(keep_v, dtype=float)

    @staticmethod
    def _take_pending(s: _Stream, keep_t: list[int], keep_v: list[np.ndarray]) -> int:
        """Move the held samples of ``s`` to the kept ones; the newest stamp [ns]."""
        for t, v in s.pending:
            keep_t.append(t)
            keep_v.append(v)
        s.pending.clear()
        return keep_t[-1]

    def _refuse_pending(self, s: _Stream) -> None:
        """Refuse the held samples of ``s`` (their stamps were a glitch)."""
        s.bad_stamp += len(s.pending)
        self.get_logger().warning(
            f'{s.name}: {len(s.pending)} sample(s) with stamps far from the others refused',
            throttle_duration_sec=5.0)
        s.pending.clear()

    def _flush(self, s: _Stream, add: Callable[[np.ndarray, np.ndarray], None]
               ) -> tuple[np.ndarray, np.ndarray] | None:
        """Hand the pending samples of one stream to the estimator ([s] since the epoch)."""
        if not s.t_ns:
            return None
        t = (np.concatenate(s.t_ns) - self._epoch_ns) * 1e-9
        v = np.concatenate(s.values)
        add(t, v)
        s.t_ns.clear()
        s.values.clear()
        return t, v

    def _flush_inputs(self) -> None:
        """Hand every pending sample to the estimator(s).

        Torque-free (``torque_topic: none``): zero torque at the gyro stamps, which is exactly
        the torque-free declaration.  While no torque message has arrived on a torque topic,
        a second estimator gets the same (:attr:`_shadow`), so that the node reports ratios
        and axes until the torque stream starts; the first torque message drops it.
        """
        gyro = self._flush(self._gyro, self._estimator.add_gyro)
        if self._joints is not None:          # wheels or rotors: no torque-free shadow
            self._flush(self._joints, self._add_joints)
            if not self._torque_free:
                self._flush(self._torque, self._estimator.add_torque)
            return
        if self._torque_free:
            if gyro is not None:
                self._estimator.add_torque(gyro[0], np.zeros_like(gyro[1]))
            return
        if self._torque.received or self._torque.before_gyro:
            self._shadow = None
        elif gyro is not None:
            if self._shadow is None:
                self._shadow = torque_free_estimator(self._cfg)()
            self._shadow.add_gyro(*gyro)
            self._shadow.add_torque(gyro[0], np.zeros_like(gyro[1]))
        self._flush(self._torque, self._estimator.add_torque)

    # ------------------------------------------------------------------ reset / clock
    def _reset(self, reason: str) -> None:
        """Forget every sample (estimator, pending buffers, epoch); counts are kept."""
        with self._lock:
            self._estimator = self._factory()
            for s in self._streams():
                s.t_ns.clear()
                s.values.clear()
                s.last_ns = None  # held samples stay: they may lead the new timeline
            if self._actuators is not None:
                self._actuators.reset()           # the motor-lag state
            self._shadow = None
            self._epoch_ns = None
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
        if not (self._fed or any(s.t_ns for s in self._streams())):
            return
        now = time.monotonic()
        due = self._last_update + 1.0 / self._cfg['publish_rate']
        if now >= due:
            self._update(now)
        elif not self._merged and now + 1.5 * self._cfg['poll_period'] >= due \
                and self._incremental():
            with self._lock:
                self._merged = True               # once per update
                if self._epoch_ns is not None and any(s.t_ns for s in self._streams()):
                    self._flush_inputs()
                    self._fed = True
                    self._core_call('merge')

    def _update(self, now: float) -> None:
        """Hand buffered samples to the core, estimate, publish everything."""
        with self._lock:
            self._last_update = now
            self._fed = self._merged = False
            if self._epoch_ns is None:
                return
            self._flush_inputs()
            est = self._estimate()
            self._update_ms = (time.monotonic() - now) * 1e3
            stamp = max(x for x in (self._gyro.last_ns, self._torque.last_ns) if x is not None)
            self._publish(est, stamp)
            # after publishing: the adequacy test the estimate deferred, for the next ones
            self._core_call('refresh')

    def _core_call(self, name: str) -> None:
        """Call the estimator's ``merge`` or ``refresh`` if it has one (off the latency path:
        :meth:`RecursiveEstimator.merge`, :meth:`RecursiveEstimator.refresh`).

        A ValueError is left to the next estimate to report; anything else is a core bug,
        reported as by :meth:`_estimate`, never a reason to stop the node.
        """
        call = getattr(self._estimator, name, None)
        if call is None:
            return
        try:
            call()
        except ValueError:
            pass
        except Exception as exc:  # a core bug must not take the node down
            self._core_error = f'estimator error: {type(exc).__name__}: {exc}'
            self.get_logger().error(self._core_error, throttle_duration_sec=5.0)

    def _estimate(self) -> InertiaEstimate:
        """The core's estimate; a core error becomes ``insufficient_data`` with its reason.

        ValueError from the core means the data cannot give an estimate yet (too few
        samples, no overlap of the streams); anything else is a bug worth an ERROR
        diagnostic, but never a reason to stop the node.
        """
        try:
            est = self._estimator.estimate()
            self._core_error = None
            if self._joints is not None and est.status == 'insufficient_data' \
                    and not self._torque_free and not self._torque.received:
                est.diagnostics['reason'] = (
                    f'no torque message on {self._torque.topic} yet: the {self._actuators.kind} '
                    'input waits for it (set torque_topic:=none when the '
                    f'{self._actuators.kind} are the only known torque)')
            if self._shadow is not None and est.status == 'insufficient_data':
                free = self._shadow.estimate()
                if free.status != 'insufficient_data':
                    free.diagnostics['reason'] = (
                        f'no torque message on {self._torque.topic} yet: torque-free estimate '
                        '(ratios and principal axes only)')
                    return free
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
            cov = messages.estimate_covariance(est)
            if cov is not None:
                self._pub_cov.publish(messages.covariance_msg(*cov))
        self._last_estimate = est
        if status != self._status:
            reason = est.diagnostics.get('reason') if status != 'ok' else ''
            self.get_logger().info(f'status {self._status or "start"} -> {status}'
                                   + (f': {reason}' if reason else ''))
            self._status = status
        diag = est.diagnostics
        have_axes = est.principal_moments is not None and est.principal_axes is not None \
            and np.all(np.isfinite(est.principal_moments)) \
            and np.all(np.isfinite(est.principal_axes))
        if have_axes:
            self._pub_moments.publish(
                messages.principal_moments_msg(est.principal_moments, stamp, frame))
            if diag.get('principal_moments_std') is not None:
                self._pub_moments_std.publish(messages.vector3_stamped(
                    stamp, diag['principal_moments_std'], frame))
        ratios = diag.get('principal_ratios')
        if ratios is not None and np.all(np.isfinite(ratios)):
            self._pub_ratios.publish(messages.vector3_stamped(stamp, ratios, frame))
            if diag.get('principal_ratios_std') is not None:
                self._pub_ratios_std.publish(messages.vector3_stamped(
                    stamp, diag['principal_ratios_std'], frame))
        if est.principal_axes is not None and np.all(np.isfinite(est.principal_axes)):
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
        for s in self._streams(timeouts=True):
            if s.last_rx is None:
                if now - self._started > timeout:
                    out.append((DiagnosticStatus.WARN, f'no {s.name} message on {s.topic} yet'))
            elif now - s.last_rx > timeout:
                out.append((DiagnosticStatus.WARN, f'{s.name} stream on {s.topic} silent for '
                            f'{now - s.last_rx:.1f} s (timeout {timeout:g} s)'))
        if self._frame_problem and now - self._frame_problem[0] <= max(timeout,
                                                                   2 * DIAGNOSTIC_PERIOD):
            out.append((DiagnosticStatus.ERROR, self._frame_problem[1]))
        if self._joints is not None and self._joints.received and self._joints.last_ns is None \
                and not self._joints.before_gyro:
            out.append((DiagnosticStatus.WARN, (
                f'joints: {self._joints.received} JointState messages on '
                f'{self._joints.topic}, none with a velocity for every joint of '
                f'{self._actuators.file} '
                f'({", ".join(self._actuators.joints)})')))
        limit = self._cfg['max_refused_fraction']
        for s in self._streams():
            frac, n = s.refused_fraction(now)
            if n >= REFUSED_MIN_SAMPLES and frac > limit:
                out.append((DiagnosticStatus.WARN, (
                    f'{s.name}: {100 * frac:.0f} % of {n} samples refused over the last '
                    f'{REFUSED_WINDOW:g} s (limit {100 * limit:g} %; so far {s.nan_dropped} '
                    f'NaN/Inf, {s.bad_stamp} invalid stamps, {s.refused} wrong frame, '
                    f'{s.malformed} malformed)')))
        if self._core_error:
            out.append((DiagnosticStatus.ERROR, self._core_error))
        return out

    def counts(self) -> dict[str, Any]:
        """Node-level counts and ages reported in the diagnostics (also used by tests)."""
        now = time.monotonic()
        out: dict[str, Any] = {}
        for s in self._streams():
            out[f'{s.name}_received'] = s.received
            out[f'{s.name}_malformed'] = s.malformed
            out[f'{s.name}_nan_dropped'] = s.nan_dropped
            out[f'{s.name}_out_of_order_dropped'] = s.out_of_order
            out[f'{s.name}_frame_refused'] = s.refused
            out[f'{s.name}_bad_stamp_refused'] = s.bad_stamp
            out[f'{s.name}_refused_fraction'] = s.refused_fraction(now)[0]
        out['torque_before_gyro_dropped'] = self._torque.before_gyro
        for s in self._streams():
            out[f'{s.name}_age_s'] = None if s.last_rx is None else now - s.last_rx
        out['resets'] = self._resets
        out['last_reset_reason'] = self._reset_reason or ''
        out['frame_id'] = self._frame or ''
        out['update_ms'] = self._update_ms
        return out

    def _streams(self, timeouts: bool = False) -> tuple[_Stream, ...]:
        """The input streams (with ``timeouts``: those a silence of is a problem)."""
        out = (self._gyro,) if (timeouts and self._torque_free) else (self._gyro, self._torque)
        return out + ((self._joints,) if self._joints is not None else ())

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
