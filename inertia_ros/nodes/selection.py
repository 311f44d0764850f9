"""Which online estimator the ``inertia_estimator`` node runs, from its parameters.

Pure selection logic (no rclpy): the node's parameter values go in, a factory of a core
online estimator (:class:`inertia_ros.core.estimation.windowed.OnlineEstimator`) comes out,
validated by building one.
"""
from __future__ import annotations

from collections.abc import Callable
from typing import Any

from inertia_ros.core.estimation.recursive import RecursiveEstimator
from inertia_ros.core.estimation.recursive_momentum import (
    MomentumRecursiveEstimator,
    MomentumTrackingEstimator,
)
from inertia_ros.core.estimation.tracking import TrackingEstimator
from inertia_ros.core.estimation.windowed import BatchWindow, OnlineEstimator

__all__ = ['BATCH_DEFAULT_WINDOW', 'TRACKING_DEFAULT_WINDOW', 'no_torque_topic',
           'make_estimator', 'reselect_every', 'torque_free_estimator']

BATCH_DEFAULT_WINDOW = 30.0  # s, batch re-solve when window = 0
TRACKING_DEFAULT_WINDOW = 10.0  # s, tracking memory when window = 0


def no_torque_topic(cfg: dict[str, Any]) -> bool:
    """Whether ``torque_topic`` is 'none' (no torque stream: torque-free estimation)."""
    return str(cfg['torque_topic']).strip().lower() == 'none'


def reselect_every(cfg: dict[str, Any]) -> int:
    """Model-selection period of the recursive estimator [updates]: about once a second."""
    return max(1, round(float(cfg['publish_rate'])))


def _calibration(cfg: dict[str, Any]) -> dict[str, float]:
    """The stated calibration uncertainties (torque and gyro scale, 1 sigma, fractions)."""
    return dict(torque_scale_std=float(cfg['torque_scale_std']),
                gyro_scale_std=float(cfg['gyro_scale_std']))


def make_estimator(cfg: dict[str, Any], actuators: Any = None
                   ) -> Callable[[], OnlineEstimator]:
    """Return a factory for the online estimator described by ``cfg`` (validated now).

    Parameters
    ----------
    cfg : dict
        The node's parameter values (``method``, ``batch_method``, ``model``,
        ``symmetry_axis``, ``torque_bias``, ``forgetting``, ``window`` [s], ``hold``,
        ``publish_rate`` [Hz], ``wheels_file``, ``rotors_file``, ``torque_topic``,
        ``torque_scale_std``, ``gyro_scale_std``, ``inertial_torque``: the recursive
        method's only; the others refuse anything but 'off' in one line).
    actuators : inertia_ros.io.rotors.ActuatorInput, optional
        Wheels or rotors on ``joint_states``: a
        :class:`~inertia_ros.core.estimation.recursive_momentum.MomentumRecursiveEstimator`
        with their uncertain inputs (``method='tracking'``: a ``MomentumTrackingEstimator``),
        or (``method='batch'``) a ``BatchWindow`` with
        ``momentum=True`` (another torque only when ``torque_topic`` is not 'none').

    Returns
    -------
    callable
        ``() -> OnlineEstimator``: a RecursiveEstimator (``method='recursive'``), a
        TrackingEstimator (``'tracking'``: memory ``window`` or 10 s) or a BatchWindow
        (``'batch'``: window ``window`` or 30 s).

    Raises
    ------
    ValueError
        From the core, naming the offending setting.
    """
    axis = cfg['symmetry_axis'] or None
    inertial = _inertial(cfg, actuators)
    if cfg['method'] == 'recursive':
        # model selection ('auto') re-run about once a second, its choice reused in between:
        # the per-update cost (and so the latency) stays that of one fit
        kwargs = dict(model=cfg['model'], torque_bias=cfg['torque_bias'],
                      forgetting=float(cfg['forgetting']),
                      window=float(cfg['window']) or None, hold=cfg['hold'],
                      symmetry_axis=axis, reselect_every=reselect_every(cfg),
                      # the once-a-second adequacy test runs after publishing (refresh()),
                      # not between the newest input and the estimate
                      defer_adequacy=True, **_calibration(cfg), **inertial)
        RecursiveEstimator(**kwargs)  # validates
        if actuators is not None:
            names = actuators.names
            other = not no_torque_topic(cfg)
            return lambda: MomentumRecursiveEstimator(names=names, other_torque=other, **kwargs)
        return lambda: RecursiveEstimator(**kwargs)
    if cfg['method'] == 'tracking' and no_torque_topic(cfg) and actuators is None:
        return torque_free_estimator(cfg)
    if cfg['method'] == 'tracking':
        # hold 'auto': a twin filter until the batch rule settles (core tracking_hold)
        kwargs = dict(window=float(cfg['window']) or TRACKING_DEFAULT_WINDOW,
                      model=cfg['model'], torque_bias=cfg['torque_bias'], hold=cfg['hold'],
                      symmetry_axis=axis, **_calibration(cfg))
        if actuators is not None:   # the momentum input reduced as the recursive mode's
            kwargs.update(names=actuators.names, other_torque=not no_torque_topic(cfg))
            MomentumTrackingEstimator(**kwargs)  # validates
            return lambda: MomentumTrackingEstimator(**kwargs)
        TrackingEstimator(**kwargs)  # validates
        return lambda: TrackingEstimator(**kwargs)
    # the batch window holds the torque: its re-solve at every update compares no holds
    cfg = dict(cfg, hold='zoh') if cfg['hold'] == 'auto' else cfg
    window = float(cfg['window']) or BATCH_DEFAULT_WINDOW
    options = dict(method=cfg['batch_method'], model=cfg['model'],
                   torque_bias=cfg['torque_bias'], hold=cfg['hold'], symmetry_axis=axis,
                   **_calibration(cfg))
    if actuators is not None:       # each re-solve: the batch momentum estimator
        options.update(momentum=True, other_torque=not no_torque_topic(cfg))
    BatchWindow(window, **options)  # validates
    return lambda: BatchWindow(window, **options)


def _inertial(cfg: dict[str, Any], actuators: Any) -> dict[str, str]:
    """The ``inertial_torque`` keyword of the recursive estimator (``{}``: without it); a
    one-line ValueError when another method, or wheels/rotors, are asked for it (``'on'``;
    ``'auto'``, the default, runs without it there)."""
    value = str(cfg.get('inertial_torque', 'auto'))
    if value == 'off' or value == 'auto' and (cfg['method'] != 'recursive'
                                              or actuators is not None):
        return {}
    if cfg['method'] != 'recursive':
        raise ValueError(f"parameter 'inertial_torque' must be 'off' or 'auto' with method "
                         f"{cfg['method']!r} (its estimator has no inertial torque), got "
                         f"{value!r}: use method 'recursive'")
    if actuators is not None:
        raise ValueError(f"parameter 'inertial_torque' must be 'off' or 'auto' with wheels or "
                         f"rotors (not available with a momentum input yet), got {value!r}")
    return {'inertial_torque': value}


def torque_free_estimator(cfg: dict[str, Any]) -> Callable[[], OnlineEstimator]:
    """The factory for torque-free data: ``make_estimator``'s, but the recursive estimator
    (memory ``window`` or 10 s) for ``method='tracking'``, whose Kalman filter needs the
    torque for the scale (the recursive one gives the ratios and axes, ``scale_unobservable``).
    """
    if cfg['method'] != 'tracking':
        return make_estimator(cfg)
    return make_estimator(dict(cfg, method='recursive',
                               window=float(cfg['window']) or TRACKING_DEFAULT_WINDOW))
