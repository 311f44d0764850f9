"""I/O boundary, ROS-free: MCAP / rosbag2 logs, CDR payloads and message-type metadata.

Nothing here imports rclpy or a ROS message package; the ROS message objects are built in
:mod:`inertia_ros.nodes.messages`.
"""
