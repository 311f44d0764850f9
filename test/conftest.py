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
