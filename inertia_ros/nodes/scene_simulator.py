"""``scene_simulator``: publishes a simulated scene's gyro, torque and wheel/rotor speed streams
(ROS 2 Jazzy).

The scene (YAML, docs/SCENES.md) is simulated once at start-up by the core
(:func:`inertia_ros.core.simulation.simulate`); the node then plays the streams back on a
steady-clock timer, in real time or faster/slower by ``rate``:

``imu``  (sensor_msgs/Imu; or ``omega``, geometry_msgs/Vector3Stamped, by parameter)
``torque``  (geometry_msgs/WrenchStamped, torque part); not published by a scene with wheels
            or rotors and no ``torque`` components (run the estimator with
            ``torque_topic:=none`` and ``wheels_file``/``rotors_file``)
``joint_states``  (sensor_msgs/JointState) for a scene with ``wheels`` or ``rotors``: the
            measured wheel/rotor speeds [rad/s] in ``velocity``, joints named as in the scene
            — all with sensor-data QoS
``~/truth``  (geometry_msgs/InertiaStamped, transient local): the true tensor at start and
             again at each scheduled inertia change

Header stamps are ``start + t`` where ``start`` is the node clock when playback starts and
``t`` the simulated time [s]; with ``rate`` != 1 stamps advance at the data rate, not the
wall rate.  With ``loop`` the run restarts with the same stamps (a backward jump that the
estimator answers with a clean reset).  :class:`~inertia_ros.nodes.playback.StreamPlayer`
(also used by ``bag_player``) does the timed playback.

Closed loop (``command_topic`` set, issue 28): the scene's own torque profile is not played;
:class:`ClosedLoopPlayer` integrates the body step by step
(:class:`inertia_ros.core.closed_loop.ClosedLoopBody`) under the latest torque commanded on
``command_topic`` (geometry_msgs/WrenchStamped, zero-order hold, zero before the first) and
publishes the gyro and the applied torque (as the scene's torque sensor reads it) as they
are produced, with the same stamps, truth and ``/clock`` as in open loop.  ``loop`` is
ignored in closed loop (a run cannot be replayed).
"""
from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from geometry_msgs.msg import InertiaStamped, Vector3Stamped, WrenchStamped
from rclpy.clock import Clock
from rclpy.clock_type import ClockType
from rclpy.node import Node
from rosgraph_msgs.msg import Clock as ClockMsg
from sensor_msgs.msg import Imu

from inertia_ros.nodes import messages, params
from inertia_ros.nodes._ros import latched_qos, run_node, sensor_qos, share_path
from inertia_ros.nodes.playback import PacedPlayer, PlaybackNode, spin_until_done

NODE_NAME = 'scene_simulator'


def default_scene_path() -> Path:
    """The installed (or source-tree) ``config/scenes/default.yaml``."""
    return share_path('config', 'scenes', 'default.yaml')


class SceneSimulatorNode(PlaybackNode):
    """Simulate a scene at start-up and play its streams back (see the module docstring)."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(NODE_NAME, params.SCENE_SIMULATOR, **kwargs)
        from inertia_ros.core.simulation import simulate
        from inertia_ros.io.scene_file import load_scene

        path = self.param('scene') or str(default_scene_path())
        scene = load_scene(path)
        seed = self.param('seed')
        if self.param('command_topic'):
            self._closed_loop(scene, path, None if seed < 0 else int(seed))
            return
        sim = simulate(scene, seed=None if seed < 0 else int(seed))
        self.sim = sim
        truth = [(0.0, sim.inertia)] + [(float(t), i) for t, i in sim.inertia_changes]
        joints: dict[str, Any] = {}
        if sim.t_wheel is not None and scene.wheels is not None:
            joints = {'joint_names': [w.joint for w in scene.wheels.wheels],
                      't_joint': sim.t_wheel, 'joint_speed': sim.wheel_speed}
        # an actuator scene without torque components has no torque sensor to speak of
        torque_free = bool(joints) and not scene.torque
        self.make_player(sim.t_gyro, sim.omega, None if torque_free else sim.t_torque,
                         None if torque_free else sim.torque, sim.frame_id, truth, **joints)
        torque = 'no torque' if torque_free else f'{sim.t_torque.size} torque'
        counts = (f'{sim.t_gyro.size} gyro and {torque}' if not joints else
                  f'{sim.t_gyro.size} gyro, {torque} and {sim.t_wheel.size} JointState '
                  f'({len(joints["joint_names"])} joints)')
        self.get_logger().info(
            f'scene {scene.name!r} from {path}: {counts} samples over {scene.duration:g} s, '
            f'seed {sim.seed}')


    def _closed_loop(self, scene: Any, path: str, seed: int | None) -> None:
        """Set up the closed-loop player and arm the start gate."""
        from inertia_ros.core.closed_loop import ClosedLoopBody

        body = ClosedLoopBody(scene, seed=seed)
        truth = [(0.0, np.array(scene.inertia))]
        if scene.inertia_change is not None:
            truth.append((float(scene.inertia_change.time),
                          np.array(scene.inertia_change.inertia)))
        if self.param('loop'):
            self.get_logger().warning('loop is ignored in closed loop (command_topic)')
        self.player = ClosedLoopPlayer(
            self, body, scene.gyro.frame_id, self.param('command_topic'),
            omega_msg_type=self.param('omega_msg_type'), rate=self.param('rate'),
            tick=self.param('tick'), truth=truth, qos_depth=self.param('qos_depth'),
            on_finish=self._finished, publish_clock=self.param('publish_clock'))
        self._gate = self.create_timer(0.05, self._try_start,
                                       clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.get_logger().info(
            f'scene {scene.name!r} from {path} in closed loop: torque commanded on '
            f'{self.player.command_topic}, {scene.duration:g} s, seed {seed or scene.seed}')


class ClosedLoopPlayer(PacedPlayer):
    """Integrate a body under the commanded torque and publish its sensors in real time.

    Parameters
    ----------
    node : rclpy.node.Node
        Owner of the publishers, the command subscription and the timer.
    body : ClosedLoopBody
        The scene's body (core).
    frame_id : str
        Frame of every header; commands in another (non-empty) frame are ignored.
    command_topic : str
        Topic of the torque command (geometry_msgs/WrenchStamped, torque part [N m]).
    omega_msg_type : {'imu', 'vector3'}
        Gyro message type (topic ``imu`` or ``omega``).
    rate : float
        Speed factor of the data time against the wall time (> 0).
    tick : float
        Timer period [s]: the command is held at least this long.
    truth : list of (t [s], inertia (3, 3))
        True tensors published on ``~/truth`` when the run passes their time.
    qos_depth : int
        History depth of the sensor publishers.
    on_finish : callable
        Called once at the end of the run.
    publish_clock : bool
        Publish ``/clock`` at the newest stamp of each step.
    """

    def __init__(self, node: Node, body: Any, frame_id: str, command_topic: str, *,
                 omega_msg_type: str, rate: float, tick: float,
                 truth: list[tuple[float, np.ndarray]], qos_depth: int,
                 on_finish: Callable[[], None], publish_clock: bool) -> None:
        self.node, self.body, self.frame_id = node, body, frame_id
        self.tick, self.loop = float(tick), False
        self.set_rate(rate)
        self._truth = sorted(truth, key=lambda x: x[0])
        self._on_finish = on_finish
        gyro_type = Imu if omega_msg_type == 'imu' else Vector3Stamped
        self._make_gyro = messages.imu_msg if gyro_type is Imu else messages.vector3_stamped
        self._pub_gyro = node.create_publisher(gyro_type, 'imu' if gyro_type is Imu
                                               else 'omega', sensor_qos(qos_depth))
        self._pub_torque = node.create_publisher(WrenchStamped, 'torque',
                                                 sensor_qos(qos_depth))
        self._pub_truth = node.create_publisher(InertiaStamped, '~/truth', latched_qos())
        self._pub_clock: Any = None
        self.publish_clock = publish_clock
        self._sub = node.create_subscription(WrenchStamped, command_topic, self._on_command,
                                             10)
        self.command_topic = self._sub.topic_name
        self.command = np.zeros(3)
        self.commands = 0
        self.published = [0, 0]
        self.finished = False
        self._warned: set[str] = set()
        self._timer = None
        self.epoch_ns = 0

    @property
    def publishers(self) -> list[Any]:
        """The data publishers (gyro, torque)."""
        return [self._pub_gyro, self._pub_torque]

    @property
    def duration(self) -> float:
        """Length of the run [s]."""
        return self.body.duration

    def _warn_once(self, key: str, text: str) -> None:
        if key not in self._warned:
            self._warned.add(key)
            self.node.get_logger().warning(text)

    def _on_command(self, msg: WrenchStamped) -> None:
        tau = np.array([msg.wrench.torque.x, msg.wrench.torque.y, msg.wrench.torque.z])
        if msg.header.frame_id and msg.header.frame_id != self.frame_id:
            self._warn_once('frame', f'ignoring torque commands in frame '
                                     f'{msg.header.frame_id!r}: the body frame is '
                                     f'{self.frame_id!r}')
        elif not np.all(np.isfinite(tau)):
            self._warn_once('nan', 'ignoring a torque command that is not finite')
        else:
            self.command = tau
            self.commands += 1

    def start(self, epoch_ns: int) -> None:
        """Start the run now with stamps ``epoch_ns + t`` [ns]."""
        self.epoch_ns = int(epoch_ns)
        self._t0 = time.monotonic()
        self._next_truth = 0
        self._timer = self.node.create_timer(
            self.tick, self._on_tick, clock=Clock(clock_type=ClockType.STEADY_TIME))
        self._on_tick()


    def _on_tick(self) -> None:
        t_now = (time.monotonic() - self._t0) * self.rate
        got = self.body.advance(t_now, self.command)
        epoch, frame = self.epoch_ns, self.frame_id
        stamps = [*got.t_gyro[-1:], *got.t_torque[-1:]]
        if self._publish_clock and stamps:
            self._pub_clock.publish(ClockMsg(clock=messages.ns_to_stamp(
                epoch + round(max(stamps) * 1e9))))
        while self._next_truth < len(self._truth) and self._truth[self._next_truth][0] <= t_now:
            t, inertia = self._truth[self._next_truth]
            self._pub_truth.publish(messages.inertia_stamped(inertia, epoch + round(t * 1e9),
                                                             frame))
            self._next_truth += 1
        for t, w in zip(got.t_gyro.tolist(), got.omega.tolist(), strict=True):
            self._pub_gyro.publish(self._make_gyro(epoch + round(t * 1e9), w, frame))
        for t, tau in zip(got.t_torque.tolist(), got.torque.tolist(), strict=True):
            self._pub_torque.publish(messages.wrench_msg(epoch + round(t * 1e9), tau, frame))
        self.published[0] += got.t_gyro.size
        self.published[1] += got.t_torque.size
        if self.body.finished and not self.finished:
            self.finished = True
            self.stop()
            self.node.get_logger().info(
                f'end of the closed-loop run: published {self.published[0]} gyro and '
                f'{self.published[1]} torque messages, {self.commands} commands received')
            self._on_finish()


def main(args: list[str] | None = None) -> None:
    """Run the node (``ros2 run inertia_ros scene_simulator``)."""
    run_node(SceneSimulatorNode, NODE_NAME, args, spin=spin_until_done)


if __name__ == '__main__':
    main()
