"""The core's medians (``core._numeric``): ``np.median`` bit for bit, on the data they see
(sample intervals with a handful of distinct values, held torque's zero differences, noise)."""
from __future__ import annotations

import numpy as np
import pytest

from inertia_ros.core._numeric import median, median_rows


@pytest.mark.parametrize('n', [1, 2, 3, 10, 1001, 40_000, 40_001])
def test_medians_equal_numpy(n: int) -> None:
    """Odd and even lengths; intervals of a jittered clock (few distinct values), a held
    signal's differences (mostly exact zeros) and white noise, per column and 1-D."""
    rng = np.random.default_rng(n)
    t = np.cumsum(np.round(rng.uniform(0.0049, 0.0051, n + 1), 6))
    held = np.diff(np.repeat(rng.normal(size=n // 7 + 2), 7)[:n + 1])
    cols = np.column_stack([np.diff(t), held, rng.normal(size=n)])
    assert np.array_equal(median_rows(cols), np.median(cols, axis=0))
    for c in cols.T:
        assert median(c) == float(np.median(c))
