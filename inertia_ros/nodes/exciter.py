"""``exciter``: commands a planned torque profile within limits and stops at the target sigma
(issue 28, active identification; ROS 2 Jazzy).

Publishes
    ``torque_command`` (``command_topic``; geometry_msgs/WrenchStamped, torque part [N m],
    reliable, depth 10) at ``rate`` Hz once the first gyro sample arrived; after a stop one
    final zero command and nothing more.
    ``/diagnostics`` (diagnostic_msgs/DiagnosticArray): status ``'exciter: excitation'`` once
    a second and at every change of state: OK while waiting, exciting or stopped at the
    target; WARN while a safety rule holds zero and after any other stop; ERROR after the
    estimator was lost.
Subscribes
    ``imu`` (sensor_msgs/Imu, sensor-data QoS): the body rate for the rate limit;
    ``<estimator>/inertia_covariance`` (std_msgs/Float64MultiArray, 6x6),
    ``<estimator>/principal_moments`` (Vector3Stamped) and ``<estimator>/principal_axes``
    (QuaternionStamped): the relative sigma of each principal moment and the tensor of the
    rate prediction;
    ``/diagnostics``: the estimator's ``resets`` count (an increase stops the exciter);
    ``joint_states`` (sensor_msgs/JointState, sensor-data QoS) with ``wheels`` set: the
    wheels' speeds; the exciter holds zero when a wheel would cross its ``max_speed``
    (and while no speeds arrive).

Re-planning (``replan_period`` > 0): every ``replan_period`` s of excitation, once the
estimator's tensor and covariance are at hand, a thread designs the next ``replan_horizon`` s
from the current estimate as the prior
(:func:`inertia_ros.core.excitation.replan.design_next`; with ``wheels``, within their speed
and torque limits from the speeds last measured); the running profile is replaced when the
new one is predicted better.  The diagnostics carry ``replans``,
``replan_switches``, ``replan_failures``, ``replan_predicted_rel_sigma`` and ``replan_last``.

The rules (limits, holds, stops) are :class:`inertia_ros.core.exciter_rules.ExciterRules`;
the profile is the ``scene``'s torque components on its command grid
(:class:`~inertia_ros.core.exciter_rules.TorqueSchedule`).  Times are the node clock's: run
with ``use_sim_time`` when the simulator plays at a rate other than 1 with ``publish_clock``.
"""
from __future__ import annotations

import threading
import time
from typing import Any

import numpy as np
import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import QuaternionStamped, Vector3Stamped, WrenchStamped
from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from sensor_msgs.msg import Imu, JointState
from std_msgs.msg import Float64MultiArray

from inertia_ros.core.excitation.inputs import Limits, Target
from inertia_ros.core.excitation.replan import (
    Continuation,
    Replan,
    Replanner,
    ReplanSettings,
    design_next,
    predict_omega,
    schedule_torque,
)
from inertia_ros.core.exciter_rules import (
    ExciterLimits,
    ExciterRules,
    TorqueSchedule,
    principal_rel_std,
)
from inertia_ros.nodes import messages, params
from inertia_ros.nodes._ros import run_node, sensor_qos, share_path
from inertia_ros.nodes.diagnostics import diagnostic_array, status_name

NODE_NAME = 'exciter'
DIAGNOSTIC_TASK = 'excitation'
#: Share of max_rate a re-planned profile may reach (the rules hold zero at max_rate).
REPLAN_RATE_SHARE = 0.85
#: Share of max_rate the running profile may reach on the estimate and still be kept.
KEEP_RATE_SHARE = 0.95
_LEVELS = {'waiting': DiagnosticStatus.OK, 'exciting': DiagnosticStatus.OK,
           'holding': DiagnosticStatus.WARN}


def stop_level(reason: str) -> bytes:
    """DiagnosticStatus level after a stop for ``reason``."""
    if reason == 'target_reached':
        return DiagnosticStatus.OK
    return DiagnosticStatus.ERROR if reason == 'estimator_lost' else DiagnosticStatus.WARN


class ExciterNode(Node):
    """Command the planned torque, enforce the limits, stop (see the module docstring)."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(NODE_NAME, **kwargs)
        cfg = params.declare(self, params.EXCITER)
        self.add_on_set_parameters_callback(lambda changes: SetParametersResult(
            successful=not params.check_changes(params.EXCITER, changes),
            reason=params.check_changes(params.EXCITER, changes)))
        from inertia_ros.io.scene_file import load_scene

        path = cfg['scene'] or str(share_path('config', 'scenes', 'default.yaml'))
        scene = load_scene(path)
        if not scene.torque:
            raise ValueError(f'scene {path}: no torque components to command; give a '
                             'planned scene with a torque profile')
        self.schedule = TorqueSchedule.from_scene(scene)
        over = float(np.mean(np.any(np.abs(self.schedule.torque) > cfg['max_torque'], axis=1)))
        if over >= 1.0:
            raise ValueError(f'scene {path}: every planned command exceeds max_torque '
                             f"{cfg['max_torque']:g} N m on some axis (peak "
                             f'{np.abs(self.schedule.torque).max():.4g} N m): lower the '
                             "scene's torque amplitude or raise max_torque")
        self.limits = ExciterLimits(
            max_torque=cfg['max_torque'], max_slew=cfg['max_slew'], max_rate=cfg['max_rate'],
            target_rel_std=cfg['target_rel_std'], timeout=cfg['timeout'],
            estimator_timeout=cfg['estimator_timeout'], command_period=1.0 / cfg['rate'],
            rate_margin=cfg['rate_margin'], rate_hysteresis=cfg['rate_hysteresis'],
            stall_window=cfg['stall_window'])
        self.rules = ExciterRules(self.limits, scene.inertia)
        self._wheel_index = _wheels_setup(cfg['wheels'], self.rules)
        self._replan = _replan_setup(cfg, scene, self.rules.wheels)
        self.frame_id = cfg['frame_id'] or scene.gyro.frame_id
        self.exit_on_stop = cfg['exit_on_stop']
        est = cfg['estimator'].rstrip('/') or '/inertia_estimator'
        self._est_status = status_name(est.rsplit('/', 1)[-1], 'inertia estimate')
        # Everything validated: only now the node starts talking.
        self.pub_cmd = self.create_publisher(WrenchStamped, cfg['command_topic'], 10)
        self.pub_diag = self.create_publisher(DiagnosticArray, '/diagnostics', 10)
        self.create_subscription(Imu, 'imu', self._on_imu, sensor_qos(100))
        self.create_subscription(Float64MultiArray, f'{est}/inertia_covariance',
                                 self._on_covariance, 10)
        self.create_subscription(Vector3Stamped, f'{est}/principal_moments',
                                 self._on_moments, 10)
        self.create_subscription(QuaternionStamped, f'{est}/principal_axes',
                                 self._on_axes, 10)
        self.create_subscription(DiagnosticArray, '/diagnostics', self._on_diagnostics, 10)
        if self._wheel_index:
            self.create_subscription(JointState, 'joint_states', self._on_joint_states,
                                     sensor_qos(100))
        self._cov: np.ndarray | None = None
        self._sched_t0: float | None = None      # start of the running schedule (None: t_start)
        self._replan_lock = threading.Lock()
        self._replan_out: tuple[float, Replan | None, str] | None = None
        self._pending: tuple[float, TorqueSchedule] | None = None   # (start, schedule)
        self._moments: np.ndarray | None = None
        self._axes: np.ndarray | None = None
        self._resets: int | None = None
        self.rel_std = float('nan')
        self.state, self.reason = 'waiting', 'no gyro sample yet'
        self.commands = 0            # commands published (the final zero included)
        self.max_commanded = 0.0     # largest |torque| component published [N m]
        self.final_sent = False
        self.done = False
        self._stopped_at: float | None = None
        self.create_timer(1.0 / cfg['rate'], self._on_tick)
        self.create_timer(1.0, self._publish_diagnostics)
        if over > 0.0:
            self.get_logger().warning(
                f'{100 * over:.1f} % of the planned commands exceed max_torque '
                f"{cfg['max_torque']:g} N m on some axis: zero is commanded there")
        self.get_logger().info(
            f'exciting with scene {scene.name!r} from {path} on {self.pub_cmd.topic_name}: '
            f'max_torque {self.limits.max_torque:g} N m, max_slew {self.limits.max_slew:g} '
            f'N m/s, max_rate {self.limits.max_rate:g} rad/s, target relative sigma '
            f'{self.limits.target_rel_std:g}, timeout {self.limits.timeout:g} s')

    def now_s(self) -> float:
        """Node clock [s]."""
        return self.get_clock().now().nanoseconds * 1e-9

    # ------------------------------------------------------------------ inputs
    def _on_imu(self, msg: Imu) -> None:
        w = msg.angular_velocity
        omega = np.array([w.x, w.y, w.z])
        if np.all(np.isfinite(omega)):
            self.rules.on_gyro(messages.stamp_to_ns(msg.header.stamp) * 1e-9, omega)

    def _on_joint_states(self, msg: JointState) -> None:
        """The wheels' speeds, when the message carries a finite velocity for each."""
        names = list(msg.name)
        if len(msg.velocity) != len(names):
            return
        vel = dict(zip(names, msg.velocity, strict=True))
        try:
            speeds = np.array([vel[j] for j in self._wheel_index], dtype=float)
        except KeyError:
            return
        if np.all(np.isfinite(speeds)):
            self.rules.on_wheel_speeds(messages.stamp_to_ns(msg.header.stamp) * 1e-9, speeds)

    def _on_moments(self, msg: Vector3Stamped) -> None:
        v = msg.vector
        self._moments = np.array([v.x, v.y, v.z])
        self._update_inertia()

    def _on_axes(self, msg: QuaternionStamped) -> None:
        from scipy.spatial.transform import Rotation

        q = msg.quaternion
        quat = np.array([q.x, q.y, q.z, q.w])
        if np.all(np.isfinite(quat)) and np.linalg.norm(quat) > 0.5:
            self._axes = Rotation.from_quat(quat).as_matrix()
            self._update_inertia()

    def _update_inertia(self) -> None:
        """The estimate (axes diag(moments) axes^T) replaces the prior of the rate check."""
        if self._moments is None or self._axes is None:
            return
        if np.all(np.isfinite(self._moments)) and np.all(self._moments > 0.0):
            self.rules.set_inertia(self._axes @ np.diag(self._moments) @ self._axes.T)

    def _on_covariance(self, msg: Float64MultiArray) -> None:
        try:
            cov, _ = messages.covariance_from_msg(msg)
        except ValueError:
            return
        rel = None
        if self._moments is not None and self._axes is not None:
            rel = float(np.max(principal_rel_std(cov, self._moments, self._axes)))
            self.rel_std = rel
            self._cov = cov
        self.rules.on_sigma(self.now_s(), rel)

    def _on_diagnostics(self, msg: DiagnosticArray) -> None:
        for st in msg.status:
            if st.name != self._est_status:
                continue
            values = {kv.key: kv.value for kv in st.values}
            try:
                resets = int(values.get('resets', ''))
            except ValueError:
                continue
            if self._resets is not None and resets > self._resets:
                why = values.get('last_reset_reason', '') or 'no reason given'
                self.rules.on_reset(self.now_s(), f'the estimator reset ({why})')
            self._resets = resets

    # ------------------------------------------------------------------ output
    def _on_tick(self) -> None:
        if self.final_sent:
            if self.exit_on_stop and time.monotonic() - self._stopped_at > 2.0:
                self.done = True
            return
        now = self.now_s()
        self._replan_step(now)
        t0 = self.rules.t_start if self._sched_t0 is None else self._sched_t0
        cmd = self.rules.step(now, self.schedule.at(0.0 if t0 is None else now - t0))
        if cmd.state != 'waiting':
            self._publish(cmd.torque)
        if cmd.state == 'stopped':
            self.final_sent = True
            self._stopped_at = time.monotonic()
        if (cmd.state, cmd.reason.split(':')[0]) != (self.state, self.reason.split(':')[0]):
            text = f'{self.state} -> {cmd.state}' + (f': {cmd.reason}' if cmd.reason else '')
            if cmd.state == 'holding' or (cmd.state == 'stopped'
                                          and self.rules.stop_reason != 'target_reached'):
                self.get_logger().warning(text)
            else:
                self.get_logger().info(text)
            self.state, self.reason = cmd.state, cmd.reason
            self._publish_diagnostics()
        self.state, self.reason = cmd.state, cmd.reason

    # ------------------------------------------------------------------ re-planning
    def _replan_step(self, now: float) -> None:
        """Start a re-plan from the current estimate when one is due (in a thread: the
        commands go on meanwhile); a new profile starts at the time it was designed for."""
        if self._replan is None:
            return
        book, lim, target, seed = self._replan
        with self._replan_lock:
            done, self._replan_out = self._replan_out, None
        if done is not None:
            if book.finished(now, done[1], done[2]) and not self.rules.stopped:
                t, torque = schedule_torque(done[1].profile, book.settings.horizon,
                                            1.0 / self.limits.command_period, seed)
                self._pending = (book.t_swap, TorqueSchedule(t, torque))
            self.get_logger().info(f're-plan {book.replans}: {book.last_reason}')
        if self._pending is not None and now >= self._pending[0]:
            self._sched_t0, self.schedule = self._pending
            self._pending = None
        have = self._cov is not None and self._moments is not None and self._axes is not None
        if self._pending is not None or not book.due(now, self.rules.t_start, have,
                                                     self.rules.stopped):
            return
        t_swap = book.started(now)
        inertia = self.rules.inertia.copy()
        cov, omega = self._cov.copy(), self.rules.m.omega.copy()
        speeds = None if self.rules.m.wheel_speeds is None else self.rules.m.wheel_speeds.copy()
        t0 = self.rules.t_start if self._sched_t0 is None else self._sched_t0
        at, offset = self.schedule.at, now - t0
        model = 'diagonal' if not np.any(cov[3:, :]) and not np.any(cov[:, 3:]) else 'full'

        def work() -> None:
            try:
                w = predict_omega(Continuation(at, offset), inertia, omega, t_swap - now,
                                  lim.torque_rate)
                out = (now, design_next(inertia, cov, w, lim, target, model, book.settings,
                                        book.design, seed,
                                        Continuation(at, offset + t_swap - now),
                                        self.limits.max_rate * KEEP_RATE_SHARE,
                                        wheel_speeds=speeds), '')
            except (ValueError, np.linalg.LinAlgError) as exc:
                out = (now, None, str(exc).splitlines()[0] if str(exc) else repr(exc))
            with self._replan_lock:
                self._replan_out = out

        threading.Thread(target=work, name='exciter-replan', daemon=True).start()

    def _publish(self, torque: np.ndarray) -> None:
        self.pub_cmd.publish(messages.wrench_msg(self.get_clock().now().nanoseconds, torque,
                                                 self.frame_id))
        self.commands += 1
        self.max_commanded = max(self.max_commanded, float(np.max(np.abs(torque))))

    def _publish_diagnostics(self) -> None:
        level = stop_level(self.rules.stop_reason) if self.state == 'stopped' \
            else _LEVELS.get(self.state, DiagnosticStatus.WARN)
        t0 = self.rules.t_start
        values = {'state': self.state, 'reason': self.reason,
                  'stop_reason': self.rules.stop_reason,
                  'elapsed': '' if t0 is None else f'{self.now_s() - t0:.3f}',
                  'relative_sigma': f'{self.rel_std:.6g}',
                  'target_rel_std': f'{self.limits.target_rel_std:g}',
                  'commands': str(self.commands),
                  'max_commanded_torque': f'{self.max_commanded:.6g}',
                  **({} if self._replan is None else self._replan[0].values())}
        status = DiagnosticStatus(
            level=level, name=status_name(self.get_name(), DIAGNOSTIC_TASK),
            hardware_id=self.get_name(),
            message=self.state + (f': {self.reason}' if self.reason else ''),
            values=[KeyValue(key=k, value=v) for k, v in values.items()])
        self.pub_diag.publish(diagnostic_array([status],
                                               self.get_clock().now().nanoseconds))


def _wheels_setup(path: str, rules: ExciterRules) -> list[str]:
    """Enforce the speed limits of the wheels file ``path`` ('' = none); their joints."""
    if not path:
        return []
    from inertia_ros.io.wheels import load_wheel_limits

    wheels = load_wheel_limits(path, need=('max_speed',))
    try:
        rules.set_wheels(wheels)
    except ValueError as exc:
        raise ValueError(f'{path}: {exc}') from None
    return [w.joint for w in wheels]


def _replan_setup(cfg: dict[str, Any], scene: Any, wheels: Any = ()
                  ) -> tuple[Replanner, Limits, Target, int] | None:
    """The re-planner, the design's limits (the exciter's torque and rate limits, the
    ``wheels`` file's wheels (their speed and torque limits; the re-plans start them from
    their measured speeds), the scene's sensors) and target, or None when
    ``replan_period`` is 0."""
    if cfg['replan_period'] <= 0.0:
        return None
    lim = Limits(max_torque=(cfg['max_torque'],) * 3,
                 max_rate=REPLAN_RATE_SHARE * cfg['max_rate'],
                 gyro_rate=scene.gyro.rate, torque_rate=cfg['rate'],
                 gyro_noise=scene.gyro.noise_std, torque_noise=scene.torque_sensor.noise_std,
                 torque_noise_rel=scene.torque_sensor.noise_rel, wheels=tuple(wheels))
    settings = ReplanSettings(period=cfg['replan_period'], horizon=cfg['replan_horizon'])
    target = Target(rel_std=cfg['target_rel_std'], max_duration=cfg['timeout'])
    return Replanner(settings), lim, target, int(scene.seed)


def spin_until_done(node: ExciterNode) -> None:
    """Spin until shutdown, or (``exit_on_stop``) until 2 s after the final command."""
    while rclpy.ok() and not node.done:
        rclpy.spin_once(node, timeout_sec=0.1)


def main(args: list[str] | None = None) -> None:
    """Run the node (``ros2 run inertia_ros exciter``)."""
    run_node(ExciterNode, NODE_NAME, args, spin=spin_until_done)


if __name__ == '__main__':
    main()
