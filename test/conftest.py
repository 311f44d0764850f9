"""Shared fixtures and paths for the test suite."""
from __future__ import annotations

import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

# Matplotlib must never try to open a window in tests.
os.environ.setdefault('MPLBACKEND', 'Agg')


def ros_importable() -> bool:
    """True when ROS 2's Python packages (rclpy and the message types) can be imported."""
    import importlib.util

    try:
        return all(importlib.util.find_spec(m) is not None
                   for m in ('rclpy', 'builtin_interfaces', 'geometry_msgs', 'sensor_msgs'))
    except (ImportError, ValueError):
        return False


def pytest_collection_modifyitems(config: object, items: list) -> None:
    """Tests marked ``ros`` need rclpy or ROS message packages.  ``pytest -m "not ros"``
    deselects them (Python 3.12 without ROS: the core, the command line and the fleet are
    still tested); where ROS is not importable a plain run skips them with that reason
    instead of failing."""
    if ros_importable():
        return
    import pytest

    skip = pytest.mark.skip(reason='needs ROS 2 Python packages (rclpy, message types), '
                                   'not importable by this interpreter')
    for item in items:
        if 'ros' in item.keywords:
            item.add_marker(skip)
