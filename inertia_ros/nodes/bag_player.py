"""``bag_player``: publishes a recorded log's gyro, torque and joint-speed streams (ROS 2 Jazzy).

For setups without rosbag2: reads a ``.mcap`` file or a rosbag2 directory with
:func:`inertia_ros.io.logs.read_log` (topics found by message type unless given; NaN samples,
duplicates and out-of-order stamps already cleaned, counted in the log line at start-up) and
plays the two streams back with their original relative timing (``rate`` factor, ``loop``):

``imu``  (sensor_msgs/Imu; or ``omega``, geometry_msgs/Vector3Stamped, by parameter)
``torque``  (geometry_msgs/WrenchStamped)
``joint_states``  (sensor_msgs/JointState) when the log has one JointState topic: its
            messages that carry a velocity for every joint of the first one (wheel or rotor
            speeds [rad/s]), names and velocities as recorded, position/effort dropped
``~/truth``  (geometry_msgs/InertiaStamped, transient local) when the log has ``/truth/inertia``

Header stamps are the recorded ones (``original_stamps``, default) or restamped from the node
clock at the start of playback.  A loop restarts with the same stamps, which the estimator
answers with a clean reset.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from inertia_ros.nodes import params
from inertia_ros.nodes._ros import run_node
from inertia_ros.nodes.playback import PlaybackNode, spin_until_done

NODE_NAME = 'bag_player'


def read_joint_speeds(path: str | Path) -> tuple[str, list[str], np.ndarray, np.ndarray] | None:
    """The JointState stream of a log, for playback.

    Parameters
    ----------
    path : str or Path
        ``.mcap`` file or rosbag2 directory.

    Returns
    -------
    (topic, names, t_ns, speed) or None
        ``names`` as in the first decodable message with velocities; ``t_ns`` (K,) int64
        header stamps [ns], sorted, duplicates dropped; ``speed`` (K, len(names)) [rad/s].
        None when the log has no JointState topic.

    Raises
    ------
    inertia_ros.io.logs.LogError
        Several JointState topics, or none of them with two usable messages.
    """
    from inertia_ros.io.joint_state import (
        first_joint_names,
        joint_state_topics,
        read_wheel_speeds,
    )
    from inertia_ros.io.logs import LogError

    topics = joint_state_topics(path)
    if not topics:
        return None
    if len(topics) > 1:
        raise LogError(f'{path}: several JointState topics {topics}; bag_player plays one '
                       'only: extract it (ros2 bag convert) or drop the others')
    topic = topics[0]
    names = first_joint_names(path, topic)
    if names is None:
        raise LogError(f'{topic}: no JointState message with a velocity for every name')
    _topic, t_ns, speed = read_wheel_speeds(path, names, topic, what='joints')
    return topic, names, t_ns, speed


class BagPlayerNode(PlaybackNode):
    """Read a log at start-up and play its streams back (see the module docstring)."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(NODE_NAME, params.BAG_PLAYER, **kwargs)
        from inertia_ros.io.logs import read_log

        path = self.param('path')
        if not path:
            raise ValueError("parameter 'path' is required (a .mcap file or a "
                             'rosbag2 directory)')
        log = read_log(path, omega_topic=self.param('omega_topic') or None,
                       torque_topic=self.param('torque_topic') or None)
        self.log = log
        for line in log.warnings:
            self.get_logger().warning(line)
        js = read_joint_speeds(path)
        joints: dict[str, Any] = {}
        if js is not None:
            joints = {'joint_names': js[1], 't_joint': (js[2] - int(log.epoch_ns)) / 1e9,
                      'joint_speed': js[3]}
        self.make_player(log.omega.t, log.omega.values, log.torque.t, log.torque.values,
                         log.omega.frame_id, list(log.truth), **joints)
        streams = f'{log.torque.t.size} from {log.torque.topic}'
        if js is not None:
            streams += f' and {js[2].size} from {js[0]} (JointState, joints {js[1]})'
        self.get_logger().info(
            f'{path}: {log.omega.t.size} samples from {log.omega.topic}'
            f'{" and " if js is None else ", "}{streams} (frame {log.omega.frame_id!r})')

    def start_epoch_ns(self) -> int:
        """Recorded epoch with ``original_stamps``, else the node clock now [ns]."""
        if self.param('original_stamps'):
            return int(self.log.epoch_ns)
        return super().start_epoch_ns()


def main(args: list[str] | None = None) -> None:
    """Run the node (``ros2 run inertia_ros bag_player --ros-args -p path:=LOG.mcap``)."""
    run_node(BagPlayerNode, NODE_NAME, args, spin=spin_until_done)


if __name__ == '__main__':
    main()
