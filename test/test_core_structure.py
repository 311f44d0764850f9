"""Shape of the core package: a fast estimation import.

The size limits (issue 12, now for the whole package) are checked in
``test_package_shape.py``; here: importing the estimators does not pull in ``scipy.signal``
or ``scipy.stats`` (0.8 s of start-up for two Savitzky-Golay calls and one chi-square tail).
"""
from __future__ import annotations

import subprocess
import sys

import pytest

from conftest import ROOT


@pytest.mark.parametrize('module', ['inertia_ros.core.estimation',
                                    'inertia_ros.core.estimation.batch',
                                    'inertia_ros.core.estimation.recursive',
                                    'inertia_ros.core.crlb',
                                    'inertia_ros.core.simulation'])
def test_import_does_not_load_scipy_signal_or_stats(module: str) -> None:
    """Importing an estimator (in a fresh interpreter) leaves scipy.signal/stats/linalg
    unloaded (linalg: 0.14 s that only ml's passes need, not the integral path of long logs)."""
    code = (f'import sys, {module}\n'
            "heavy = sorted(m for m in sys.modules if m.split('.')[:2] in "
            "(['scipy', 'signal'], ['scipy', 'stats'], ['scipy', 'linalg']))\n"
            'print(heavy)\n')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         check=True, cwd=ROOT)
    assert out.stdout.strip() == '[]', f'{module} imports {out.stdout.strip()}'


def test_estimation_face_is_lazy() -> None:
    """``import inertia_ros.core.estimation`` alone loads options, not the numerical modules;
    the public names still resolve on use."""
    code = ('import sys, inertia_ros.core.estimation as e\n'
            "print('inertia_ros.core.estimation.batch' in sys.modules)\n"
            'print(e.estimate.__module__, e.RecursiveEstimator.__module__, e.METHODS[0])\n')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         check=True, cwd=ROOT).stdout.split('\n')
    assert out[0] == 'False'
    assert out[1] == ('inertia_ros.core.estimation.batch '
                      'inertia_ros.core.estimation.recursive auto')


def test_online_estimator_import_loads_no_scipy() -> None:
    """The online path (the node's) imports numpy only: scipy.sparse, scipy.special and
    scipy.linalg are imported where the batch path first needs them."""
    code = ('import sys, inertia_ros.core.estimation.recursive\n'
            "print(sorted(m for m in sys.modules if m.split('.')[0] == 'scipy'))\n")
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         check=True, cwd=ROOT)
    assert out.stdout.strip() == '[]', out.stdout
