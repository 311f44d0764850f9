"""``bag_player``: publishes a recorded log's gyro and torque streams (ROS 2 Jazzy).

For setups without rosbag2: reads a ``.mcap`` file or a rosbag2 directory with
:func:`inertia_ros.io.logs.read_log` (topics found by message type unless given; NaN samples,
duplicates and out-of-order stamps already cleaned, counted in the log line at start-up) and
plays the two streams back with their original relative timing (``rate`` factor, ``loop``):

``imu``  (sensor_msgs/Imu; or ``omega``, geometry_msgs/Vector3Stamped, by parameter)
``torque``  (geometry_msgs/WrenchStamped)
``~/truth``  (geometry_msgs/InertiaStamped, transient local) when the log has ``/truth/inertia``

Header stamps are the recorded ones (``original_stamps``, default) or restamped from the node
clock at the start of playback.  A loop restarts with the same stamps, which the estimator
answers with a clean reset.
"""
from __future__ import annotations

from typing import Any

from inertia_ros.nodes import params
from inertia_ros.nodes._ros import run_node
from inertia_ros.nodes.playback import PlaybackNode, spin_until_done

NODE_NAME = 'bag_player'


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
        self.make_player(log.omega.t, log.omega.values, log.torque.t, log.torque.values,
                         log.omega.frame_id, list(log.truth))
        self.get_logger().info(
            f'{path}: {log.omega.t.size} samples from {log.omega.topic} and '
            f'{log.torque.t.size} from {log.torque.topic} (frame {log.omega.frame_id!r})')

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
