"""The estimators' vocabularies and thresholds: the one home of every rule shared by batch,
online and the command line.

This module imports nothing (not even numpy), so ``python -m inertia_ros estimate --help``
and the node's parameter table can use it without paying for the numerical stack.

Vocabularies
    :data:`METHODS`, :data:`MODELS`, :data:`TORQUE_BIAS`, :data:`HOLDS`, :data:`STATUSES`.
Rules
    :data:`MIN_GYRO_SAMPLES` (fewer used gyro samples is ``insufficient_data``),
    :data:`MIN_EQUATIONS` (fewer equations is ``insufficient_data``),
    :data:`GAP_FACTOR` (a sample interval over this many median intervals is a gap),
    :data:`TORQUE_FREE_SIGMAS` (a torque stream whose RMS is within this many noise sigmas of
    zero is torque-free), :data:`ALPHA` (level of the torque bias's test),
    :data:`IDENTIFIABILITY_TOL` (an element whose standard error exceeds this share of the
    tensor scale is not identifiable), :data:`ML_AUTO_MAX_SAMPLES`.
"""
from __future__ import annotations

__all__ = ['ADEQUACY_ALPHA', 'ADEQUACY_MIN_WINDOW_S', 'ADEQUACY_WINDOWS', 'ALPHA',
           'ATTITUDE_BRIDGE_RAD', 'BATCH_HOLDS',
           'GAP_FACTOR',
           'HOLDS', 'IDENTIFIABILITY_TOL', 'MAX_RESIDUAL_EXCESS', 'METHODS', 'MIN_EQUATIONS',
           'MIN_RESIDUAL_EXCESS',
           'MIN_GYRO_SAMPLES', 'ML_AUTO_MAX_SAMPLES', 'MODELS', 'STATUSES', 'TORQUE_BIAS',
           'NUISANCE_EIV_SHARE', 'NUISANCE_INTERVALS_S', 'NUISANCE_MAX_DELAY_S',
           'NUISANCE_MAX_TIME_CONSTANT_S',
           'INERTIAL_TORQUE', 'NUISANCE_TERMS', 'TORQUE_FREE_SIGMAS', 'check_choice',
           'check_nuisance']

#: Batch methods (``estimate(method=...)``, ``--method``).
METHODS: tuple[str, ...] = ('auto', 'ml', 'integral', 'integral_ls', 'integral_sliding',
                            'differential_fd', 'differential_sg', 'filtered')
#: Parameter sets (``model=``, ``--model``).
MODELS: tuple[str, ...] = ('auto', 'full', 'diagonal', 'axisymmetric')
#: Constant disturbance-torque choices (``torque_bias=``, ``--torque-bias``).
TORQUE_BIAS: tuple[str, ...] = ('auto', 'on', 'off')
#: A torque constant in inertial axes (``inertial_torque=``; :mod:`.attitude`): fitted beside
#: the torque bias, ``auto`` by the joint Wald tests of :func:`.selection.select_disturbance`.
INERTIAL_TORQUE: tuple[str, ...] = ('off', 'auto', 'on')
#: Largest attitude error [rad] accepted where the attitude of the inertial torque is carried
#: over a gyro gap at the mean rate of its end samples (bound ``|w_after - w_before| h / 2``);
#: beyond it the inertial torque is not fitted (``diagnostics['disturbance']['skipped']``).
ATTITUDE_BRIDGE_RAD = 0.01
#: How the torque is held between its samples (online estimators, the node's ``hold``).
HOLDS: tuple[str, ...] = ('zoh', 'linear')
#: The batch ``hold=`` / ``--hold`` choices: ``auto`` fits both and keeps the one whose
#: residuals the noise model explains better.
BATCH_HOLDS: tuple[str, ...] = ('auto', *HOLDS)
#: Every status an estimate can carry (DESIGN.md contract), best first.
STATUSES: tuple[str, ...] = ('ok', 'model_mismatch', 'scale_unobservable',
                             'partially_identifiable', 'insufficient_excitation',
                             'insufficient_data')

#: ``method='auto'`` uses ``ml`` up to this many gyro samples (500 s at 200 Hz), ``integral``
#: beyond: the likelihood passes cost ~25 us and ~2 kB per gyro sample (2.5 s and 0.2 GB
#: here), while ``integral``'s cost grows more slowly and its error is already small.
ML_AUTO_MAX_SAMPLES = 100_000
#: Fewer used gyro samples than this gives ``insufficient_data`` (batch and online).
MIN_GYRO_SAMPLES = 20
#: Fewer equations (net of segment intercepts) than this gives ``insufficient_data``: three
#: per parameter of the general model (6 tensor elements and 3 bias components).
MIN_EQUATIONS = 3 * (6 + 3)
#: A sample interval longer than this many median (nominal) intervals is a gap.
GAP_FACTOR = 5.0
#: Torque-free when every axis' torque RMS is within this many torque-noise sigmas.
TORQUE_FREE_SIGMAS = 5.0
#: Level of the torque bias's Wald test (the parameter set's: :data:`.selection.MODEL_ALPHA`).
ALPHA = 1e-3
#: An element whose standard error exceeds this share of the tensor scale is undetermined.
IDENTIFIABILITY_TOL = 0.1
#: Level of the model-adequacy window test (``model_mismatch`` below it).
ADEQUACY_ALPHA = 1e-4
#: Largest residual excess (weighted RSS over its noise-model prediction) accepted as ``ok``.
MAX_RESIDUAL_EXCESS = 1.5
#: Smallest residual excess a fit may report as ``ok``: residuals at half the noise the model
#: predicts mean the fit absorbs the noise (a near-degenerate fit, its sigma not to be
#: trusted).  Measured (session 10): 0.86-1.12 on 150 model-conforming, continuous,
#: disturbance and gyro-scale records of 2-5 s; 0.11-0.38 on the four peer-like single-axis
#: records ``ok`` at |z| 7-47.  Not applied with a wheel or rotor momentum input, whose noise
#: model is an upper bound (correct rotor fits: 0.28-0.96).
MIN_RESIDUAL_EXCESS = 0.5
#: Windows of the adequacy test, and the shortest window [s] (fewer windows on short records).
ADEQUACY_WINDOWS = 4
ADEQUACY_MIN_WINDOW_S = 5.0

#: Sensor nuisance terms (``estimate(nuisance=...)``, ``--nuisance``; :mod:`.nuisance`):
#: a constant gyro bias, a torque-to-gyro stamp offset, linear aerodynamic damping and a
#: first-order gyro low-pass.  Each is kept only when a likelihood-ratio test at ``alpha``
#: (:data:`ALPHA`, the level of the torque bias's test) supports it.
NUISANCE_TERMS: tuple[str, ...] = ('gyro_bias', 'torque_delay', 'damping', 'gyro_lowpass')
#: Largest torque-stamp offset searched [s] (either sign).
NUISANCE_MAX_DELAY_S = 0.05
#: Largest gyro low-pass time constant searched [s].
NUISANCE_MAX_TIME_CONSTANT_S = 0.05
#: Candidate lengths [s] of the independent momentum equations of the nuisance fit: the
#: shortest whose gyro-noise share (errors in variables) is at most NUISANCE_EIV_SHARE.
NUISANCE_INTERVALS_S: tuple[float, ...] = (0.1, 0.2, 0.5, 1.0, 2.0, 5.0)
NUISANCE_EIV_SHARE = 0.005


def check_choice(name: str, value: object, choices: tuple[str, ...]) -> str:
    """Return ``value`` if it is one of ``choices``, else raise one clear ``ValueError``.

    Parameters
    ----------
    name : str
        The option's name, used in the message (``'method'``, ``'model'``, ...).
    value : object
        What the user gave.
    choices : tuple of str
        The allowed values.

    Returns
    -------
    str
        ``value``, unchanged.
    """
    if not isinstance(value, str) or value not in choices:
        raise ValueError(f'{name}: must be one of {", ".join(choices)}; got {value!r}')
    return value


def check_nuisance(value: object) -> str | tuple[str, ...]:
    """The ``nuisance`` option: ``'auto'``, ``'off'`` or terms of :data:`NUISANCE_TERMS`.

    Parameters
    ----------
    value : object
        ``'auto'``, ``'off'``, a list/tuple of term names or one comma-separated string.

    Returns
    -------
    str or tuple of str
        ``'auto'``, ``'off'`` or the terms (in :data:`NUISANCE_TERMS` order, no repeats).
    """
    if value in ('auto', 'off'):
        return str(value)
    items = value.split(',') if isinstance(value, str) else value
    if not isinstance(items, (list, tuple)) or not items \
            or not all(isinstance(v, str) for v in items):
        raise ValueError(f"nuisance: must be 'auto', 'off' or a list of terms "
                         f"({', '.join(NUISANCE_TERMS)}); got {value!r}")
    names = [v.strip() for v in items]
    bad = [v for v in names if v not in NUISANCE_TERMS]
    if bad:
        raise ValueError(f"nuisance: unknown term {bad[0]!r}; use 'auto', 'off' or terms of "
                         f"{', '.join(NUISANCE_TERMS)}")
    return tuple(t for t in NUISANCE_TERMS if t in names)
