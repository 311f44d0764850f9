"""Benchmarks: speed against accuracy, efficiency against the Cramer-Rao bound, stability map.

``python -m inertia_ros bench [--quick] [--out docs/]`` (:mod:`inertia_ros.cli.bench`) runs
:func:`inertia_ros.bench.run.run_bench`, which writes ``speed_vs_accuracy.png``,
``stability_map.png``, ``BENCHMARKS.md`` and ``bench_results.json``.  Matplotlib is used here
only; the core stays free of it.
"""
