"""The ROS 2 side of inertia_ros: every rclpy and ROS message import lives in this package.

Nodes (each with a ``main()``; ``python -m inertia_ros.<name>_node`` and the ``ros2 run``
executables call them):

- :mod:`~inertia_ros.nodes.estimator`: ``inertia_estimator``, the live estimator;
- :mod:`~inertia_ros.nodes.scene_simulator`: ``scene_simulator``, a simulated scene played
  back;
- :mod:`~inertia_ros.nodes.bag_player`: ``bag_player``, a recorded log played back.

Their parts: :mod:`~inertia_ros.nodes._ros` (``main()``, QoS, polled input, share dir),
:mod:`~inertia_ros.nodes.params` and :mod:`~inertia_ros.nodes.params_file` (parameters,
``--params-file``), :mod:`~inertia_ros.nodes.messages` (messages <-> arrays),
:mod:`~inertia_ros.nodes.diagnostics`, :mod:`~inertia_ros.nodes.markers` and
:mod:`~inertia_ros.nodes.playback` (the players' common base); the estimator's
:mod:`~inertia_ros.nodes.selection` (which online estimator),
:mod:`~inertia_ros.nodes.admission` (input checks and counts),
:mod:`~inertia_ros.nodes.feed` (feeding and asking the estimator) and
:mod:`~inertia_ros.nodes.outputs` (result topics).  The numerics are in
:mod:`inertia_ros.core`, files and payload codecs in :mod:`inertia_ros.io` (neither imports
ROS).
"""
