"""StreamingNoise: the online noise level depends on the stream, not on its blocks or calls."""
from __future__ import annotations

import numpy as np

from inertia_ros.core.estimation.noise import StreamingNoise, noise_std_from_differences


def _feed(x: np.ndarray, block: int, ask_every: int) -> np.ndarray:
    s = StreamingNoise(floor=False)
    for k, i in enumerate(range(0, len(x), block)):
        s.add(x[i:i + block])
        if k % ask_every == 0:
            s.std()
    return s.std()


def test_noise_level_is_independent_of_blocks_and_calls():
    """Blocks of 1, 7, 100 and 5000 samples, asked after every block or every 13th: the same
    std to the last bit, equal to the batch rule on the 4096 samples ending at the latest
    multiple of 1024 (here 9216 of 10 000)."""
    rng = np.random.default_rng(3)
    t = np.arange(10_000) * 1e-3
    x = np.c_[np.sin(t), np.cos(2 * t), t] + rng.normal(0.0, [0.01, 0.02, 0.03], (10_000, 3))
    got = [_feed(x, b, a) for b in (1, 7, 100, 5000) for a in (1, 13)]
    for g in got[1:]:
        assert np.array_equal(g, got[0])
    np.testing.assert_array_equal(got[0], noise_std_from_differences(x[9216 - 4096:9216]))
    np.testing.assert_allclose(got[0], [0.01, 0.02, 0.03], rtol=0.05)


def test_short_stream_uses_every_sample_until_the_first_stride():
    """Before 1024 samples the estimate follows every new sample (a starting node)."""
    rng = np.random.default_rng(4)
    x = rng.normal(0.0, 0.05, (600, 3))
    s = StreamingNoise(floor=False)
    s.add(x[:300])
    first = s.std().copy()
    s.add(x[300:])
    np.testing.assert_array_equal(first, noise_std_from_differences(x[:300]))
    np.testing.assert_array_equal(s.std(), noise_std_from_differences(x))
