"""inertia_ros: rigid-body inertia tensor estimation from gyro and known-torque streams.

Layers (one way only):

``inertia_ros.core``
    Pure numpy/scipy: tensors and bodies, Euler's equations, regressors, estimators,
    identifiability, model selection, scene simulation.  Never imports rclpy or mcap.
``inertia_ros.io``
    MCAP / rosbag2 reading and writing, message <-> array conversion.
``inertia_ros.*_node``
    rclpy nodes: parameters, topics and timers wired to the core.
``inertia_ros.cli``
    Offline commands (``python -m inertia_ros estimate|simulate|bench|demo``).
"""

__version__ = '0.1.0'
