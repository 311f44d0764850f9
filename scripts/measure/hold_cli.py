"""The CLI path (MCAP written, read back, estimate LOG with defaults) on the scene-like cases."""

import sys

from inertia_ros.bench.honesty import HonestyCase, render, run_case, summarize
from inertia_ros.bench.truth_sim import TruthCase

SCENE = TruthCase(amplitude=0.06, torque_noise=0.0012, omega0=(0.05, -0.03, 0.02))
kind, n = sys.argv[1], int(sys.argv[2])
out = run_case(kind, HonestyCase(SCENE.with_(torque_kind=kind)), range(n), ("cli",))
print(render(summarize(out)))
