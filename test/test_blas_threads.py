"""One BLAS thread while an estimate runs (inertia_ros.core._blas)."""
import os

import pytest

from inertia_ros.bench.common import nominal_scene
from inertia_ros.core import _blas
from inertia_ros.core.estimation import batch
from inertia_ros.core.simulation import simulate

_USER_SET = 'OPENBLAS_NUM_THREADS' in os.environ or 'OMP_NUM_THREADS' in os.environ


def _counts():
    return [lib.num_threads for lib in _blas.blas_libraries()]


@pytest.mark.skipif(_USER_SET, reason='the thread count set in the environment stands')
def test_one_thread_inside_restored_after_also_nested():
    import scipy.linalg  # noqa: F401  (its own OpenBLAS, loaded lazily by ml)
    if not _blas.blas_libraries():
        pytest.skip('no BLAS threadpoolctl can control in this process')
    for lib in _blas.blas_libraries():
        lib.set_num_threads(2)
    before = _counts()
    with _blas.one_blas_thread():
        assert _counts() == [1] * len(before)
        with _blas.one_blas_thread():
            assert _counts() == [1] * len(before)
        assert _counts() == [1] * len(before)       # still inside the outer call
    assert _counts() == before


@pytest.mark.skipif(_USER_SET, reason='the thread count set in the environment stands')
def test_estimate_runs_on_one_thread(monkeypatch):
    """The estimate's products see one thread, and the count is back afterwards."""
    if not _blas.blas_libraries():
        pytest.skip('no BLAS threadpoolctl can control in this process')
    seen = []
    inner = batch._estimate_direct

    def spy(*a, **k):
        seen.append(_counts())
        return inner(*a, **k)
    monkeypatch.setattr(batch, '_estimate_direct', spy)
    for lib in _blas.blas_libraries():
        lib.set_num_threads(2)
    before = _counts()
    sim = simulate(nominal_scene(10.0), seed=1)
    batch.estimate(sim.t_gyro, sim.omega, sim.t_torque, sim.torque, method='integral')
    assert seen and all(c == [1] * len(c) for c in seen)
    assert _counts() == before


def test_user_setting_stands(monkeypatch):
    monkeypatch.setenv('OPENBLAS_NUM_THREADS', '2')
    got = _counts()
    with _blas.one_blas_thread():
        assert _counts() == got
