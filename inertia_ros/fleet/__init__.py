"""Many logs at once: ``python -m inertia_ros fleet PATH... --out FILE``.

Every log found under the given paths is estimated with the same options and the same JSON
contract as ``python -m inertia_ros estimate`` (DESIGN.md), one Dask task per log, and becomes
one row of a table (Parquet or CSV).  Re-runs are incremental; ``--report DIR`` draws a trend
per vehicle and flags the logs whose tensor jumped.

Modules
-------
discover
    Find the logs (``.mcap`` files, rosbag2 directories, recursive search, fsspec URLs).
run
    The per-log task, the Dask client and the submission loop (progress, Ctrl-C, re-runs).
table
    Rows <-> Parquet / CSV.
report
    Trend plots, outlier table and status counts (PNG + Markdown).

Importing this package is cheap: Dask, pyarrow and matplotlib are imported only where used.
"""
from __future__ import annotations

__all__ = ['discover', 'report', 'run', 'table']
