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
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

from inertia_ros.nodes import params
from inertia_ros.nodes._ros import run_node, share_path
from inertia_ros.nodes.playback import PlaybackNode, spin_until_done

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


def main(args: list[str] | None = None) -> None:
    """Run the node (``ros2 run inertia_ros scene_simulator``)."""
    run_node(SceneSimulatorNode, NODE_NAME, args, spin=spin_until_done)


if __name__ == '__main__':
    main()
