"""The estimate command's numbers (report) and figure (plots): sigma bands and measured torque
are visible, the series are right."""
from __future__ import annotations

import matplotlib

matplotlib.use('Agg')
import matplotlib.pyplot as plt
import numpy as np
import pytest

from conftest import ROOT
from inertia_ros.cli.plots import _convergence_panel, _torque_panels
from inertia_ros.cli.report import build_report, convergence, format_text, window_torques
from inertia_ros.core.estimation import estimate
from inertia_ros.io.logs import read_log

DEFAULT_BAG = ROOT / 'bags' / 'default.mcap'
pytestmark = pytest.mark.skipif(not DEFAULT_BAG.exists(), reason='bags/default.mcap absent')


@pytest.fixture(scope='module')
def fitted() -> tuple:
    """The default bag, read and estimated with the command's defaults."""
    log = read_log(DEFAULT_BAG)
    est = estimate(log.omega.t, log.omega.values, log.torque.t, log.torque.values)
    return est, log


def test_window_torques_model_matches_measured(fitted: tuple) -> None:
    """On the simulated bag the model torque tracks the measured one: residual RMS below
    10 % of the torque RMS on every axis."""
    est, log = fitted
    t, meas, model = window_torques(est, log.omega.t, log.omega.values, log.torque.t,
                                    log.torque.values, 'zoh', 1.0)
    assert t.size > 1000 and meas.shape == model.shape == (t.size, 3)
    resid = np.sqrt(np.mean((meas - model) ** 2, axis=0))
    scale = np.sqrt(np.mean(meas ** 2, axis=0))
    assert np.all(resid < 0.1 * scale), (resid, scale)


def test_convergence_against_truth_is_calibrated(fitted: tuple) -> None:
    """Prefix estimates converge: the full-log deviation from the truth is within 4 sigma
    per element, and sigma shrinks from the shortest to the full prefix."""
    est, log = fitted
    conv = convergence(est, log)
    assert conv is not None and conv.reference_name == 'truth' and not conv.ratios
    assert conv.seconds[-1] == pytest.approx(log.omega.t[-1] - log.omega.t[0])
    np.testing.assert_array_equal(conv.theta[-1], est.theta)
    z = conv.relative[-1] / conv.relative_std[-1]
    assert np.all(np.abs(z) < 4.0), z
    assert np.all(conv.relative_std[-1] < conv.relative_std[0])


def test_sigma_bands_are_visible(fitted: tuple) -> None:
    """The +-2 sigma band of every element at the full log spans at least 5 % of the
    convergence panel's height (at full scale it was under 0.1 %)."""
    est, log = fitted
    conv = convergence(est, log)
    fig, ax = plt.subplots()
    try:
        _convergence_panel(ax, conv, est.status)
        lo, hi = ax.get_ylim()
        band = 4 * 100.0 * conv.relative_std[-1]
        assert np.all(band / (hi - lo) > 0.05), band / (hi - lo)
        assert len(ax.collections) == 6                      # one band per element
    finally:
        plt.close(fig)


def test_measured_torque_is_drawn_as_markers_under_the_model_line(fitted: tuple) -> None:
    """Each torque panel draws the measured torque as open markers (no line) and the model
    as a line on top; a fourth panel draws the residual."""
    est, log = fitted
    fig, axes = plt.subplots(4, 1)
    try:
        _torque_panels(list(axes), est, log, 'zoh')
        for ax in axes[:3]:
            meas = [ln for ln in ax.lines if ln.get_label() == 'measured']
            model = [ln for ln in ax.lines if ln.get_label() == 'model']
            assert len(meas) == 1 and len(model) == 1
            assert meas[0].get_linestyle() == 'None' and meas[0].get_marker() == 'o'
            assert model[0].get_zorder() > meas[0].get_zorder()
            assert 10 < len(meas[0].get_xdata()) <= 260
        assert 'residual' in axes[3].get_title()
    finally:
        plt.close(fig)


def test_text_report_from_the_report_dict(fitted: tuple) -> None:
    """format_text renders the values with their sigma and the numerical warnings passed in."""
    est, log = fitted
    rep = build_report(est, log, 0.0, 'zoh', ['numerical warning: x (RuntimeWarning, 2x)'])
    text = format_text(rep)
    assert 'status: ok' in text and '±' in text
    assert '  - numerical warning: x (RuntimeWarning, 2x)' in text
    assert rep['diagnostics']['warnings'].count('numerical warning: x (RuntimeWarning, 2x)') == 1
