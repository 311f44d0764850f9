"""Timed playback of gyro, torque and joint-speed arrays as ROS messages: the base of both
players.

:class:`StreamPlayer` publishes ``imu`` (sensor_msgs/Imu; or ``omega``, geometry_msgs/
Vector3Stamped), ``torque`` (geometry_msgs/WrenchStamped; absent for torque-free data),
``joint_states`` (sensor_msgs/JointState: wheel or rotor speeds, when the data have them) with
sensor-data QoS and
``~/truth`` (geometry_msgs/InertiaStamped, latched) on a steady-clock timer, in real time or
faster/slower by ``rate``; with ``publish_clock`` also ``/clock`` (rosgraph_msgs/Clock, clock
QoS) carrying the data time, for nodes run with ``use_sim_time``.  :class:`PlaybackNode`
declares the playback parameters shared by ``scene_simulator`` and ``bag_player``, gates the
start on subscribers, and ends the process at the end of the data when asked
(:func:`spin_until_done`).
"""
from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import rclpy
from geometry_msgs.msg import InertiaStamped, Vector3Stamped, WrenchStamped
from rcl_interfaces.msg import (
    FloatingPointRange,
    IntegerRange,
    ParameterDescriptor,
    SetParametersResult,
)
from rclpy.clock import Clock
from rclpy.clock_type import ClockType
from rclpy.node import Node
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock as ClockMsg
from sensor_msgs.msg import Imu, JointState

from inertia_ros.nodes import messages, params
from inertia_ros.nodes._ros import clock_qos, latched_qos, sensor_qos
from inertia_ros.nodes.params import ParamSpec

__all__ = ['PlaybackNode', 'StreamPlayer', 'declare_playback_parameters', 'double_descriptor',
           'integer_descriptor',
           'spin_until_done', 'validate_playback']

_NS = 1_000_000_000
#: Wait after the subscriptions are matched before playback starts [s] (see _try_start).
#: The subscriber's side of a match lags the publisher's: 1-75 ms measured between two
#: processes on this 2-core machine (idle and loaded).  A full test run once lost 140 ms of
#: data time in both streams with a 0.3 s settle, which fits a lag over 0.37 s; 1 s covers
#: such a tail at the cost of one second before a simulated scene starts.
MATCH_SETTLE = 1.0


class PacedPlayer:
    """What every player shares: the speed factor, the steady timer and the optional ``/clock``.

    Subclasses set ``node``, ``rate``, ``_timer`` (None until started), ``_t0`` (the wall time
    of data time 0, :func:`time.monotonic`), ``_publish_clock`` and ``_pub_clock``.
    """

    node: Node
    rate: float
    _t0: float
    _timer: Any
    _publish_clock: bool
    _pub_clock: Any

    @property
    def publish_clock(self) -> bool:
        """Whether ``/clock`` is published (the publisher is created when first needed)."""
        return self._publish_clock

    @publish_clock.setter
    def publish_clock(self, on: bool) -> None:
        self._publish_clock = bool(on)
        if self._publish_clock and self._pub_clock is None:
            self._pub_clock = self.node.create_publisher(ClockMsg, '/clock', clock_qos())

    def set_rate(self, rate: float) -> None:
        """Change the speed factor (> 0) without a jump in the data time."""
        if not (rate > 0 and np.isfinite(rate)):
            raise ValueError(f'rate must be a positive finite speed factor, got {rate!r}')
        if getattr(self, '_timer', None) is not None:
            now = time.monotonic()
            self._t0 = now - (now - self._t0) * self.rate / rate
        self.rate = float(rate)

    def stop(self) -> None:
        """Stop the timer (idempotent)."""
        if self._timer is not None:
            self._timer.cancel()
            self.node.destroy_timer(self._timer)
            self._timer = None


class StreamPlayer(PacedPlayer):
    """Play gyro, torque and joint-speed arrays back with their original relative timing.

    Parameters
    ----------
    node : rclpy.node.Node
        Owner of the publishers and the timer.
    t_gyro : numpy.ndarray, shape (N,)
        Gyro stamps [s] relative to ``epoch_ns``, non-decreasing.
    omega : numpy.ndarray, shape (N, 3)
        Angular velocity [rad/s].
    t_torque : numpy.ndarray, shape (M,), or None
        Torque stamps [s] relative to ``epoch_ns``, non-decreasing.  None (with ``torque``
        None): no ``torque`` topic at all (torque-free data, e.g. a wheels-only scene).
    torque : numpy.ndarray, shape (M, 3), or None
        Torque [N m].
    frame_id : str
        Frame written into every header.
    omega_msg_type : {'imu', 'vector3'}
        Gyro message type (topic ``imu`` or ``omega``).
    rate : float
        Playback speed factor (> 0): 2 plays twice as fast as recorded.
    loop : bool
        Restart from the beginning (same stamps) when the end is reached.
    tick : float
        Timer period [s].
    truth : list of (t [s], inertia (3, 3)), optional
        True tensors to publish on ``~/truth`` when playback passes their time.
    qos_depth : int
        History depth of the sensor publishers.
    on_finish : callable, optional
        Called once when the end is reached without ``loop``.
    publish_clock : bool
        Also publish ``/clock`` (rosgraph_msgs/Clock): at every step that publishes samples
        or truth, before them, the newest stamp of that step [ns] (``epoch_ns + t``), so a
        node with ``use_sim_time`` reads a clock at the stamps it receives.  It advances with
        the data (``rate`` times the wall rate) and jumps back with them at a ``loop``.
        Settable later through :attr:`publish_clock`.
    joint_names : sequence of str, optional
        Joints of ``joint_speed``'s columns (wheels or rotors); with them the player publishes
        ``joint_states`` (sensor_msgs/JointState, ``name`` and ``velocity`` only).
    t_joint : numpy.ndarray, shape (K,), optional
        JointState stamps [s] relative to ``epoch_ns``, non-decreasing.
    joint_speed : numpy.ndarray, shape (K, n_joints), optional
        Joint speeds [rad/s].

    Raises
    ------
    ValueError
        On mismatched shapes, unsorted stamps, a bad rate/tick or message type.
    """

    def __init__(self, node: Node, t_gyro: np.ndarray, omega: np.ndarray,
                 t_torque: np.ndarray, torque: np.ndarray, frame_id: str, *,
                 omega_msg_type: str = 'imu', rate: float = 1.0, loop: bool = False,
                 tick: float = 0.005, truth: list[tuple[float, np.ndarray]] | None = None,
                 qos_depth: int = 100, on_finish: Callable[[], None] | None = None,
                 publish_clock: bool = False, joint_names: Sequence[str] = (),
                 t_joint: np.ndarray | None = None,
                 joint_speed: np.ndarray | None = None) -> None:
        has_torque = t_torque is not None or torque is not None
        t_gyro = np.asarray(t_gyro, dtype=float)
        t_torque = np.asarray(t_torque if has_torque else [], dtype=float)
        omega = np.asarray(omega, dtype=float)
        torque = np.asarray(torque if has_torque else np.zeros((0, 3)), dtype=float)
        self.joint_names = [str(n) for n in joint_names]
        t_joint = np.asarray(t_joint if t_joint is not None else [], dtype=float)
        joint_speed = np.asarray(joint_speed if joint_speed is not None
                                 else np.zeros((0, len(self.joint_names))), dtype=float)
        if omega.shape != (t_gyro.size, 3):
            raise ValueError(f'omega must have shape ({t_gyro.size}, 3), got {omega.shape}')
        if torque.shape != (t_torque.size, 3):
            raise ValueError(f'torque must have shape ({t_torque.size}, 3), got {torque.shape}')
        if joint_speed.shape != (t_joint.size, len(self.joint_names)):
            raise ValueError(f'joint_speed must have shape ({t_joint.size}, '
                             f'{len(self.joint_names)}) for joints {self.joint_names}, '
                             f'got {joint_speed.shape}')
        if t_joint.size and not self.joint_names:
            raise ValueError('t_joint given without joint_names')
        for name, t in (('t_gyro', t_gyro), ('t_torque', t_torque), ('t_joint', t_joint)):
            if t.size and np.any(np.diff(t) < 0):
                raise ValueError(f'{name} must be non-decreasing')
        if omega_msg_type not in ('imu', 'vector3'):
            raise ValueError(f"omega_msg_type must be 'imu' or 'vector3', got {omega_msg_type!r}")
        self.node = node
        self.frame_id = frame_id
        self.loop = loop
        self.tick = float(tick)
        self.set_rate(rate)
        # One merged, time-ordered event list: (time [s], kind 0 = gyro / 1 = torque /
        # 2 = joints, index).
        times = np.concatenate([t_gyro, t_torque, t_joint])
        kinds = np.concatenate([np.zeros(t_gyro.size, int), np.ones(t_torque.size, int),
                                np.full(t_joint.size, 2)])
        idx = np.concatenate([np.arange(t_gyro.size), np.arange(t_torque.size),
                              np.arange(t_joint.size)])
        order = np.lexsort((kinds, times))
        self._times = times[order]
        self._kinds = kinds[order].tolist()
        self._index = idx[order].tolist()
        self._t_ns = [np.round(t_gyro * _NS).astype(np.int64).tolist(),
                      np.round(t_torque * _NS).astype(np.int64).tolist(),
                      np.round(t_joint * _NS).astype(np.int64).tolist()]
        self._vals = [omega.tolist(), torque.tolist(), joint_speed.tolist()]
        self._truth = sorted(truth or [], key=lambda x: x[0])
        self._on_finish = on_finish
        if omega_msg_type == 'imu':
            self._pub_gyro = node.create_publisher(Imu, 'imu', sensor_qos(qos_depth))
            self._make_gyro = messages.imu_msg
        else:
            self._pub_gyro = node.create_publisher(Vector3Stamped, 'omega', sensor_qos(qos_depth))
            self._make_gyro = messages.vector3_stamped
        self._pub_torque = (node.create_publisher(WrenchStamped, 'torque', sensor_qos(qos_depth))
                            if has_torque else None)
        self._pub_joints = (node.create_publisher(JointState, 'joint_states',
                                                  sensor_qos(qos_depth))
                            if self.joint_names else None)
        self._pub_truth = node.create_publisher(InertiaStamped, '~/truth', latched_qos())
        self._pub_clock: Any = None
        self.clock_ns: int | None = None  # last time published on /clock [ns]
        self.publish_clock = publish_clock
        self.epoch_ns = 0
        self.published = [0, 0]  # gyro, torque messages
        self.published_joints = 0  # JointState messages
        self.loops = 0
        self.finished = False
        self._timer = None
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)

    @property
    def clock_publisher(self) -> Any:
        """The ``/clock`` publisher, or None while ``publish_clock`` was never on."""
        return self._pub_clock

    def _publish_clock_at(self, stamp_ns: int) -> None:
        """Publish ``stamp_ns`` on ``/clock`` (when on and not already published)."""
        if not self._publish_clock or stamp_ns == self.clock_ns:
            return
        self._pub_clock.publish(ClockMsg(clock=messages.ns_to_stamp(stamp_ns)))
        self.clock_ns = stamp_ns

    @property
    def gyro_publisher(self) -> Any:
        """The gyro publisher (for subscription counts)."""
        return self._pub_gyro

    @property
    def torque_publisher(self) -> Any:
        """The torque publisher (for subscription counts); None without a torque stream."""
        return self._pub_torque

    @property
    def joint_publisher(self) -> Any:
        """The ``joint_states`` publisher; None without joint speeds."""
        return self._pub_joints

    @property
    def publishers(self) -> list[Any]:
        """The data publishers in use (gyro, then torque and joints when present)."""
        return [p for p in (self._pub_gyro, self._pub_torque, self._pub_joints)
                if p is not None]

    @property
    def duration(self) -> float:
        """Time span of the data [s]."""
        return float(self._times[-1]) if self._times.size else 0.0

    def start(self, epoch_ns: int) -> None:
        """Start playback now with stamps ``epoch_ns + t`` [ns]."""
        self.epoch_ns = int(epoch_ns)
        self._t0 = time.monotonic()
        self._next = 0
        self._next_truth = 0
        self._timer = self.node.create_timer(self.tick, self._on_tick, clock=self._steady)
        self._on_tick()

    def _on_tick(self) -> None:
        t_now = (time.monotonic() - self._t0) * self.rate
        end = int(np.searchsorted(self._times, t_now, side='right'))
        if self._publish_clock:
            # the step's newest stamp, before its samples: the clock is at them on arrival
            newest = None
            if end > self._next:
                newest = self._t_ns[self._kinds[end - 1]][self._index[end - 1]]
            n_truth = self._next_truth
            while n_truth < len(self._truth) and self._truth[n_truth][0] <= t_now:
                n_truth += 1
            if n_truth > self._next_truth:
                t_truth = round(self._truth[n_truth - 1][0] * _NS)
                newest = t_truth if newest is None else max(newest, t_truth)
            if newest is not None:
                self._publish_clock_at(self.epoch_ns + newest)
        while self._next_truth < len(self._truth) and self._truth[self._next_truth][0] <= t_now:
            t, inertia = self._truth[self._next_truth]
            self._pub_truth.publish(messages.inertia_stamped(
                inertia, self.epoch_ns + round(t * _NS), self.frame_id))
            self._next_truth += 1
        frame, epoch = self.frame_id, self.epoch_ns
        for k in range(self._next, end):
            kind, i = self._kinds[k], self._index[k]
            stamp = epoch + self._t_ns[kind][i]
            if kind == 0:
                self._pub_gyro.publish(self._make_gyro(stamp, self._vals[0][i], frame))
            elif kind == 1:
                self._pub_torque.publish(messages.wrench_msg(stamp, self._vals[1][i], frame))
            else:
                self._pub_joints.publish(messages.joint_state_msg(
                    stamp, self.joint_names, self._vals[2][i]))
                self.published_joints += 1
                continue
            self.published[kind] += 1
        self._next = end
        if end >= len(self._kinds) and self._next_truth >= len(self._truth):
            if self.loop:
                self.loops += 1
                self._t0 = time.monotonic()
                self._next = 0
                self._next_truth = 0
                self.node.get_logger().info(f'end of data: loop {self.loops} starts')
            elif not self.finished:
                self.finished = True
                self.stop()
                counts = (f'{self.published[0]} gyro and {self.published[1]} torque'
                          if self._pub_joints is None else
                          f'{self.published[0]} gyro, {self.published[1]} torque and '
                          f'{self.published_joints} JointState')
                self.node.get_logger().info(f'end of data: published {counts} messages')
                if self._on_finish is not None:
                    self._on_finish()


def double_descriptor(description: str, lo: float, hi: float, read_only: bool = False
            ) -> ParameterDescriptor:
    """A floating-point parameter descriptor with range ``[lo, hi]``."""
    return ParameterDescriptor(description=description, read_only=read_only,
                               floating_point_range=[FloatingPointRange(
                                   from_value=lo, to_value=hi, step=0.0)])


def integer_descriptor(description: str, lo: int, hi: int, read_only: bool = False
             ) -> ParameterDescriptor:
    """An integer parameter descriptor with range ``[lo, hi]``."""
    return ParameterDescriptor(description=description, read_only=read_only,
                               integer_range=[IntegerRange(from_value=lo, to_value=hi, step=0)])


def declare_playback_parameters(node: Node,
                                specs: dict[str, ParamSpec] | None = None) -> dict[str, Any]:
    """Declare a player's parameters (default: the shared :data:`.params.PLAYBACK` ones).

    Values as typed by a ROS user are coerced and checked (:func:`.params.declare`); a bad
    one raises a one-line ValueError, an unknown name is warned about.
    """
    return params.declare(node, specs if specs is not None else params.PLAYBACK)


def validate_playback(changes: list[Parameter],
                      specs: dict[str, ParamSpec] | None = None) -> str:
    """Return '' when the playback parameter changes are valid, else the one-line reason."""
    return params.check_changes(specs if specs is not None else params.PLAYBACK, changes)


class PlaybackNode(Node):
    """Base of the two players: parameters, start gating, rate changes, exit at the end."""

    def __init__(self, name: str, specs: dict[str, ParamSpec] | None = None,
                 **kwargs: Any) -> None:
        super().__init__(name, **kwargs)
        self.specs = specs if specs is not None else params.PLAYBACK
        declare_playback_parameters(self, self.specs)
        self.player: StreamPlayer | None = None
        self._waiting_logged = False
        self._matched_at: float | None = None
        self.done = False
        self._created = time.monotonic()
        self._gate = None
        self.add_on_set_parameters_callback(self._on_set_parameters)

    def param(self, name: str) -> Any:
        """Current value of a parameter."""
        return self.get_parameter(name).value

    def _on_set_parameters(self, changes: list[Parameter]) -> SetParametersResult:
        problem = validate_playback(changes, self.specs) or self.validate_more(changes)
        if problem:
            return SetParametersResult(successful=False, reason=problem)
        for p in changes:
            if self.player is not None and p.name == 'rate':
                self.player.set_rate(float(p.value))
            if self.player is not None and p.name == 'loop':
                self.player.loop = bool(p.value)
            if self.player is not None and p.name == 'publish_clock':
                self.player.publish_clock = bool(p.value)
        return SetParametersResult(successful=True)

    def validate_more(self, params: list[Parameter]) -> str:
        """Node-specific validation; '' when valid."""
        return ''

    def make_player(self, t_gyro: np.ndarray, omega: np.ndarray, t_torque: np.ndarray | None,
                    torque: np.ndarray | None, frame_id: str,
                    truth: list[tuple[float, np.ndarray]], joint_names: Sequence[str] = (),
                    t_joint: np.ndarray | None = None,
                    joint_speed: np.ndarray | None = None) -> StreamPlayer:
        """Create the player from the parameters and arm the start gate.

        ``t_torque``/``torque`` None: no torque topic; ``joint_names`` with ``t_joint`` (K,)
        [s] and ``joint_speed`` (K, n) [rad/s]: a ``joint_states`` topic (see
        :class:`StreamPlayer`).
        """
        self.player = StreamPlayer(
            self, t_gyro, omega, t_torque, torque, frame_id,
            omega_msg_type=self.param('omega_msg_type'), rate=self.param('rate'),
            loop=self.param('loop'), tick=self.param('tick'), truth=truth,
            qos_depth=self.param('qos_depth'), on_finish=self._finished,
            publish_clock=self.param('publish_clock'), joint_names=joint_names,
            t_joint=t_joint, joint_speed=joint_speed)
        self._gate = self.create_timer(0.05, self._try_start,
                                       clock=Clock(clock_type=ClockType.STEADY_TIME))
        return self.player

    def _try_start(self) -> None:
        assert self.player is not None
        want = self.param('wait_for_subscribers')
        pubs = self.player.publishers
        matched = min(p.get_subscription_count() for p in pubs)
        waited = time.monotonic() - self._created
        timeout = self.param('wait_timeout')
        if matched < want:
            # discovery is per topic: wait until every stream is matched
            if not self._waiting_logged:
                self._waiting_logged = True
                self.get_logger().info(
                    f'waiting for {want} subscriber(s) on '
                    + ' and '.join(p.topic_name for p in pubs) + ' (wait_for_subscribers; '
                    + (f'at most {timeout:g} s)' if timeout > 0 else 'no timeout)'))
            if timeout <= 0 or waited < timeout:
                return
            self.get_logger().warning(
                f'starting without the subscribers: only {matched} of {want} matched after '
                f'{timeout:g} s (wait_timeout)')
        elif want > 0:
            # Matching is seen from the publisher's side first; the subscriber's side may
            # learn of this writer a little later, and best-effort samples sent before that
            # are lost.  A short settle time after the match covers it.
            if self._matched_at is None:
                self._matched_at = time.monotonic()
            if time.monotonic() - self._matched_at < MATCH_SETTLE:
                return
        if waited < self.param('start_delay'):
            return
        self._gate.cancel()
        self.destroy_timer(self._gate)
        self._gate = None
        self.player.start(self.start_epoch_ns())
        self.get_logger().info(
            f'playing {self.player.duration:.1f} s of data at rate {self.player.rate:g}')

    def start_epoch_ns(self) -> int:
        """Stamp [ns] of data time zero."""
        return self.get_clock().now().nanoseconds

    def _finished(self) -> None:
        if self.param('exit_on_end'):
            self.done = True


def spin_until_done(node: PlaybackNode) -> None:
    """Spin until shutdown or, with ``exit_on_end``, until the data end (+2 s linger).

    The linger matters: a process that exits right after its last publish can take the
    last messages with it before a busy subscriber has pulled them from the transport.
    """
    while rclpy.ok() and not node.done:
        rclpy.spin_once(node, timeout_sec=0.1)
    if node.done:
        end = time.monotonic() + 2.0
        while rclpy.ok() and time.monotonic() < end:
            rclpy.spin_once(node, timeout_sec=0.05)
