"""Shape of the nodes package (issue 26): nodes wire ROS to the core, logic lives elsewhere.

The size limits are checked once for the whole package (``test_package_shape.py``); here:
the estimator's non-ROS parts
(estimator selection, input admission, feeding, the params-file check) import no rclpy, so
they can be used and tested without ROS.
"""
from __future__ import annotations

import json
import subprocess
import sys

from conftest import ROOT

NODES = ROOT / 'inertia_ros' / 'nodes'
#: The estimator's helpers without ROS (only numpy, the core, io codecs, yaml).
ROS_FREE = ('selection', 'admission', 'feed', 'params_file')


def test_estimator_helpers_import_no_ros() -> None:
    """Importing the estimator's helpers in a fresh interpreter loads no rclpy or messages."""
    mods = [f'inertia_ros.nodes.{m}' for m in ROS_FREE]
    code = ('import importlib, json, sys\n'
            f'for m in {mods!r}:\n'
            '    importlib.import_module(m)\n'
            'print(json.dumps(sorted(m for m in sys.modules if m.split(".")[0] == "rclpy"\n'
            '                        or m.split(".")[0].endswith("_msgs"))))\n')
    proc = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                          cwd=ROOT, check=False)
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout.strip().splitlines()[-1]) == []
