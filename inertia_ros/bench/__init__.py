"""Benchmarks, one home: ``python -m inertia_ros bench [KIND]`` (:mod:`inertia_ros.cli.bench`).

Without KIND, the accuracy suite (:func:`inertia_ros.bench.run.run_bench`): speed against
accuracy, efficiency against the Cramer-Rao bound, the stability map and the start-up times;
it writes ``speed_vs_accuracy.png``, ``stability_map.png``, ``BENCHMARKS.md`` and
``bench_results.json``.  Focused benchmarks print their figures:

:mod:`~inertia_ros.bench.startup`
    start-up of the command line and the node as whole processes;
:mod:`~inertia_ros.bench.estimators`
    batch speed on a 1M-sample record, recursive cost per sample, accuracy per method;
:mod:`~inertia_ros.bench.recursive`
    the recursive estimator driven as the node drives it;
:mod:`~inertia_ros.bench.offline`
    reading, decoding and estimating a long MCAP log against ``mcap`` and ``mcap_ros2``;
:mod:`~inertia_ros.bench.node`
    the estimator node as a process fed at 1 kHz + 1 kHz (needs ROS 2);
:mod:`~inertia_ros.bench.simulate`
    simulating and writing a scene.

Matplotlib is used here (:mod:`~inertia_ros.bench.plots`, whose :data:`METHOD_STYLE` gives
each method its one colour and name) and in :mod:`inertia_ros.cli.plots` only; the core stays
free of it.
"""
