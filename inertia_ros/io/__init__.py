"""I/O boundary: MCAP / rosbag2 logs and ROS messages to and from numpy arrays."""
