"""One options object validated once, and the one capability table ``mode x feature x input``.

Every estimator entry point (:func:`.batch.estimate`, :func:`.momentum.estimate_with_momentum`,
:class:`.recursive.RecursiveEstimator`, :class:`.recursive_momentum.MomentumRecursiveEstimator`,
:class:`.tracking.TrackingEstimator`, :class:`.windowed.BatchWindow`) calls :func:`require` at
its top with its mode, its input kind and its options.  :func:`require` builds one
:class:`EstimatorOptions` (the vocabularies and ranges checked once) and looks every feature the
options ask for up in :data:`CAPABILITIES`: a combination the table does not support is refused
with one ``ValueError`` line taken from the table (mode, input, feature and what to use
instead), never a ``TypeError`` and never a silent substitution.

Modes (:data:`MODES`)
    ``batch`` (:func:`.batch.estimate`, :func:`.momentum.estimate_with_momentum`),
    ``recursive`` (the node's ``method='recursive'``), ``tracking``, ``window`` (the node's
    ``method='batch'``, :class:`.windowed.BatchWindow`).
Inputs (:data:`INPUTS`)
    ``torque``, ``wheels``, ``rotors``, ``torque_free``, ``wheels_torque`` (wheels and another
    known torque).
Features (:data:`FEATURES`)
    ``hold_auto``, ``hold_zoh``, ``hold_linear``, ``model_auto``, ``torque_bias_auto``,
    ``nuisance``, ``torque_scale_std``, ``gyro_scale_std``, ``inertial_torque`` (options a
    caller asks for; ``inertial_torque`` is asked for by ``'on'``: its default ``'auto'``
    runs without the term where a mode or input has none, and says so) and
    ``adequacy`` (whether the status can say ``model_mismatch``: not an option, so the table
    states it and :func:`require` never refuses on it).

This module imports only :mod:`.options` and numpy.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from .options import (
    ALPHA,
    BATCH_HOLDS,
    IDENTIFIABILITY_TOL,
    INERTIAL_TORQUE,
    MODELS,
    TORQUE_BIAS,
    check_choice,
    check_nuisance,
)

__all__ = ['CAPABILITIES', 'FEATURES', 'INPUTS', 'MODES', 'SUBSTITUTED', 'YES',
           'EstimatorOptions', 'capability_table', 'refusal', 'require', 'substitutions',
           'unapplied']

#: Estimation modes.
MODES: tuple[str, ...] = ('batch', 'recursive', 'tracking', 'window')
#: Input kinds (how the known angular impulse arrives).
INPUTS: tuple[str, ...] = ('torque', 'wheels', 'rotors', 'torque_free', 'wheels_torque')
#: Rows of the table: ``input`` (the mode takes this input at all), then the features.
FEATURES: tuple[str, ...] = ('input', 'hold_auto', 'hold_zoh', 'hold_linear', 'model_auto',
                             'torque_bias_auto', 'nuisance', 'torque_scale_std',
                             'gyro_scale_std', 'inertial_torque', 'adequacy')
#: How each feature is named in a refusal.
_LABELS = {'input': 'this input', 'hold_auto': "hold='auto'", 'hold_zoh': "hold='zoh'",
           'hold_linear': "hold='linear'", 'model_auto': "model='auto'",
           'torque_bias_auto': "torque_bias='auto'", 'nuisance': 'nuisance terms',
           'torque_scale_std': 'torque_scale_std > 0', 'gyro_scale_std': 'gyro_scale_std > 0',
           'inertial_torque': "inertial_torque='on'",
           'adequacy': 'the adequacy test (model_mismatch)'}

#: A supported cell.
YES = 'yes'
#: Prefix of a cell run as something else (documented here, not refused: see the cell).
SUBSTITUTED = 'runs as '

_NO_NUISANCE = 'nuisance terms are fitted by the batch estimator only; use batch mode'
#: the momentum inputs without a torque stream: the torque sensor's scale has nothing to scale
_TORQUE_SCALE_MOM = (SUBSTITUTED + 'torque_scale_std=0: no torque stream to scale (the '
                     'wheel/rotor momentum is never scaled by it; state the wheel inertia_std '
                     'or rotor k_f_std/k_m_std/inertia_std for that)')


def _row(torque: str = YES, wheels: str = YES, rotors: str = YES, torque_free: str = YES,
         wheels_torque: str = YES) -> dict[str, str]:
    """One table row: the cell of each input kind (``YES`` or what to use instead)."""
    return {'torque': torque, 'wheels': wheels, 'rotors': rotors, 'torque_free': torque_free,
            'wheels_torque': wheels_torque}


def _all(note: str) -> dict[str, str]:
    """A row with the same cell ``note`` for every input kind."""
    return dict.fromkeys(INPUTS, note)


_TF_TORQUE_SCALE = (SUBSTITUTED + 'torque_scale_std=0: a torque scale has no effect on '
                    'torque-free equations (diagnostics.calibration records it)')
_TF_NUISANCE = (SUBSTITUTED + "nuisance='off': no torque stream to offset or filter "
                               '(diagnostics.nuisance.skipped says so)')

#: the inertial torque (issue 27, docs/dev/inertial_torque_design.md section 6)
_MOM_INERTIAL = ("the inertial torque is fitted on a torque input only yet (the stated "
                 "wheel/rotor profile has none); use inertial_torque='off' with wheels or "
                 "rotors")
_TF_INERTIAL = (SUBSTITUTED + "inertial_torque='off': no torque to give the scale (an inertial "
                              'torque of unknown size is no scale source)')
_WINDOW_INERTIAL = ("the node's window re-solves have no inertial torque yet; use recursive "
                    'or batch mode')
_TRACKING_INERTIAL = 'the tracking filter has no inertial torque; use batch mode'

_MOM_NUISANCE = "nuisance terms are fitted on a torque stream only; use nuisance='off' with "\
    'wheels or rotors'

#: ``CAPABILITIES[mode][feature][input]``: :data:`YES`, or the refusal's "what instead".
CAPABILITIES: dict[str, dict[str, dict[str, str]]] = {
    'batch': {
        'input': _row(),
        'hold_auto': _row(),
        'hold_zoh': _row(), 'hold_linear': _row(),
        'model_auto': _row(), 'torque_bias_auto': _row(),
        'nuisance': _row(wheels=_MOM_NUISANCE, rotors=_MOM_NUISANCE, torque_free=_TF_NUISANCE,
                         wheels_torque=_MOM_NUISANCE),
        # the torque sensor's scale: of the other torque only (issue 26 defect 4)
        'torque_scale_std': _row(wheels=_TORQUE_SCALE_MOM, rotors=_TORQUE_SCALE_MOM,
                                 torque_free=_TF_TORQUE_SCALE),
        'gyro_scale_std': _row(),
        'inertial_torque': _row(wheels=_MOM_INERTIAL, rotors=_MOM_INERTIAL,
                                torque_free=_TF_INERTIAL, wheels_torque=_MOM_INERTIAL),
        'adequacy': _row(),
    },
    # the batch cells but the nuisance terms (derived below): both holds' statistics on the
    # same rows, chosen by the batch rule (online_hold.py); with wheels/rotors the other
    # torque's two reductions (nothing held without one)
    'recursive': {},
    'tracking': {
        # wheels and rotors: the momentum input reduced as the recursive mode's (one road)
        'input': _row(torque_free='the tracking filter needs torque for the scale; use '
                                  'recursive mode (ratios and axes)'),
        # a twin filter under the other hold until the batch rule decides (tracking_hold.py)
        'hold_auto': _row(),
        'hold_zoh': _row(), 'hold_linear': _row(),
        # substituted today (the node's default torque_bias is 'auto'): to be refused once
        # the node passes an explicit choice to the tracker
        'model_auto': _all(SUBSTITUTED + "model='full' (no selection); give it explicitly, "
                           'or use recursive mode'),
        'torque_bias_auto': _all(SUBSTITUTED + "torque_bias='off' (no test); give 'on' or "
                                 "'off' explicitly, or use recursive mode"),
        'nuisance': _all(_NO_NUISANCE),
        'torque_scale_std': _row(wheels=_TORQUE_SCALE_MOM, rotors=_TORQUE_SCALE_MOM),
        'gyro_scale_std': _row(), 'inertial_torque': _all(_TRACKING_INERTIAL),
        'adequacy': _row(),
    },
    # each re-solve is the batch estimator on the window (the momentum inputs: its
    # estimate_with_momentum), so the cells are the batch ones: derived, not copied
    'window': {},
}
CAPABILITIES['recursive'] = {feature: dict(row) for feature, row in CAPABILITIES['batch'].items()}
CAPABILITIES['recursive']['nuisance'] = _all(_NO_NUISANCE)
CAPABILITIES['window'] = {feature: dict(row) for feature, row in CAPABILITIES['batch'].items()}
# the node's window re-solves take no inertial_torque parameter yet
CAPABILITIES['window']['inertial_torque'] = _all(_WINDOW_INERTIAL)


@dataclass(frozen=True)
class EstimatorOptions:
    """The options every estimator shares, validated once (one ``ValueError`` line each).

    Attributes
    ----------
    model : {'auto', 'full', 'diagonal', 'axisymmetric'}
        Parameter set.
    torque_bias : {'auto', 'on', 'off'}
        Constant disturbance torque [N m]; a bool is taken as ``'on'``/``'off'``.
    hold : {'auto', 'zoh', 'linear'}
        Torque between its samples.
    symmetry_axis : {'x', 'y', 'z'}, array_like (3,) or None
        Body symmetry axis; required for ``model='axisymmetric'``.
    alpha : float
        Level of the torque bias's test, in (0, 1) (the parameter set's is fixed, 5 %).
    identifiability_tol : float
        Largest standard error of an identifiable element, share of the tensor scale (> 0).
    torque_scale_std, gyro_scale_std : float
        Relative one-sigma scale uncertainties in [0, 0.5] (0.01 = 1 %).
    nuisance : 'auto', 'off' or tuple of str
        Sensor nuisance terms (:data:`.options.NUISANCE_TERMS`).
    inertial_torque : {'auto', 'off', 'on'}
        A disturbance torque constant in inertial axes (:data:`.options.INERTIAL_TORQUE`);
        ``'auto'`` (the estimators' default) is no request where the term is absent.
    """

    model: str = 'auto'
    torque_bias: Any = 'auto'
    hold: str = 'auto'
    symmetry_axis: Any = None
    alpha: float = ALPHA
    identifiability_tol: float = IDENTIFIABILITY_TOL
    torque_scale_std: float = 0.0
    gyro_scale_std: float = 0.0
    nuisance: Any = 'off'
    inertial_torque: str = 'auto'

    def __post_init__(self) -> None:
        """Check every option once; normalise ``torque_bias`` and ``nuisance``."""
        check_choice('model', self.model, MODELS)
        tb = self.torque_bias
        if isinstance(tb, (bool, np.bool_)):
            object.__setattr__(self, 'torque_bias', 'on' if tb else 'off')
        check_choice('torque_bias', self.torque_bias, TORQUE_BIAS)
        check_choice('hold', self.hold, BATCH_HOLDS)
        _check_axis(self.symmetry_axis, self.model)
        if not _is_real(self.alpha) or not 0.0 < self.alpha < 1.0:
            raise ValueError(f'alpha: must be in (0, 1), got {self.alpha!r}')
        if not _is_real(self.identifiability_tol) or not self.identifiability_tol > 0.0:
            raise ValueError(f'identifiability_tol: must be > 0, got '
                             f'{self.identifiability_tol!r}')
        for name in ('torque_scale_std', 'gyro_scale_std'):
            v = getattr(self, name)
            if not _is_real(v) or not 0.0 <= v <= 0.5:
                raise ValueError(f'{name}: must be a relative one-sigma scale uncertainty in '
                                 f'[0, 0.5] (0.01 = 1 %), got {v!r}')
        object.__setattr__(self, 'nuisance', check_nuisance(self.nuisance))
        check_choice('inertial_torque', self.inertial_torque, INERTIAL_TORQUE)

    def features(self) -> tuple[str, ...]:
        """The table rows these options ask for (``input`` first)."""
        out = ['input', f'hold_{self.hold}']
        if self.model == 'auto':
            out.append('model_auto')
        if self.torque_bias == 'auto':
            out.append('torque_bias_auto')
        if self.nuisance != 'off':
            out.append('nuisance')
        out += [n for n in ('torque_scale_std', 'gyro_scale_std') if getattr(self, n) > 0]
        if self.inertial_torque == 'on':         # ('auto' runs without it where it is absent)
            out.append('inertial_torque')
        return tuple(out)


def _is_real(v: Any) -> bool:
    """A finite real number (not a bool)."""
    return (not isinstance(v, (bool, np.bool_)) and isinstance(v, (int, float, np.number))
            and bool(np.isfinite(v)))


def _check_axis(axis: Any, model: str) -> None:
    """``symmetry_axis``: None, 'x'/'y'/'z' or three finite numbers, not all zero."""
    if axis is None:
        if model == 'axisymmetric':
            raise ValueError("symmetry_axis: required for model='axisymmetric'")
        return
    if isinstance(axis, str):
        check_choice('symmetry_axis', axis, ('x', 'y', 'z'))
        return
    try:
        a = np.asarray(axis, dtype=float)
    except (TypeError, ValueError):
        a = np.zeros(0)
    if a.shape != (3,) or not np.all(np.isfinite(a)) or not np.any(a):
        raise ValueError(f"symmetry_axis: must be 'x', 'y', 'z' or 3 finite numbers, not all "
                         f'zero; got {axis!r}')


def refusal(mode: str, input_kind: str, feature: str) -> str | None:
    """The one-line refusal of a cell, or None when the table supports it.

    Parameters
    ----------
    mode, input_kind, feature : str
        One of :data:`MODES`, :data:`INPUTS`, :data:`FEATURES`.
    """
    cell = CAPABILITIES[mode][feature][input_kind]
    if cell == YES or cell.startswith(SUBSTITUTED):
        return None
    what = 'input' if feature == 'input' else _LABELS[feature]
    return (f'{mode} mode, {input_kind} input: {what} is not supported; {cell}')


def substitutions(mode: str, input_kind: str, opts: EstimatorOptions) -> list[str]:
    """The table's lines for the ``runs as`` cells the options ask for (for the warnings).

    Parameters
    ----------
    mode, input_kind : str
        One of :data:`MODES`, :data:`INPUTS`.
    opts : EstimatorOptions
        The validated options.

    Returns
    -------
    list of str
        ``'<mode> mode, <input> input: <feature> runs as ...'`` per substituted feature.
    """
    out = []
    for feature in opts.features():
        cell = CAPABILITIES[mode][feature][input_kind]
        if cell.startswith(SUBSTITUTED):
            out.append(f'{mode} mode, {input_kind} input: {_LABELS[feature]} {cell}')
    return out


def unapplied(mode: str, opts: Any) -> list[str]:
    """The table's lines for the stated calibration a torque-free fit does not apply.

    For torque-free data found from the data (a torque stream within its noise), after
    :func:`require` has passed the options: the estimators put these lines in
    ``diagnostics['warnings']`` instead of dropping the stated uncertainty silently.

    Parameters
    ----------
    mode : str
        One of :data:`MODES`.
    opts : object
        Anything with ``torque_scale_std`` and ``gyro_scale_std`` (relative, >= 0).

    Returns
    -------
    list of str
        One line per stated uncertainty the table refuses for torque-free input.
    """
    out = []
    for name in ('torque_scale_std', 'gyro_scale_std'):
        message = refusal(mode, 'torque_free', name)
        if getattr(opts, name, 0.0) > 0 and message is not None:
            out.append(message)
    return out


def require(mode: str, input_kind: str, opts: EstimatorOptions | Mapping[str, Any]
            ) -> EstimatorOptions:
    """Validate the options once and refuse what the capability table does not support.

    Parameters
    ----------
    mode : str
        One of :data:`MODES`.
    input_kind : str
        One of :data:`INPUTS`.
    opts : EstimatorOptions or mapping
        The options; a mapping may hold other keys (ignored here).

    Returns
    -------
    EstimatorOptions
        The validated options.

    Raises
    ------
    ValueError
        One line: a malformed option, or the table's refusal (mode, input, feature and what
        to use instead).
    """
    check_choice('mode', mode, MODES)
    check_choice('input', input_kind, INPUTS)
    if not isinstance(opts, EstimatorOptions):
        names = {f.name for f in fields(EstimatorOptions)}
        opts = EstimatorOptions(**{k: v for k, v in opts.items() if k in names})
    for feature in opts.features():
        message = refusal(mode, input_kind, feature)
        if message is not None:
            raise ValueError(message)
    return opts


def _shown(mode: str, feature: str, input_kind: str) -> str:
    """A cell as the table shows it (``-`` for a feature of an input the mode refuses)."""
    cell = CAPABILITIES[mode][feature][input_kind]
    if feature != 'input' and CAPABILITIES[mode]['input'][input_kind] != YES:
        return '-'
    return cell if cell == YES or cell.startswith(SUBSTITUTED) else f'no: {cell}'


def capability_table() -> str:
    """The table as Markdown, one block per mode (docs/DESIGN.md, "Capability table").

    Returns
    -------
    str
        Rows = features, columns = inputs; ``yes``, ``no: <what instead>``,
        ``runs as <what it does>`` (a substitution the table states; not refused yet) or
        ``-`` (the mode refuses the input).
    """
    lines = []
    for mode in MODES:
        lines += [f'**{mode}**', '', '| feature | ' + ' | '.join(INPUTS) + ' |',
                  '|---|' + '---|' * len(INPUTS)]
        for feature in FEATURES:
            cells = [_shown(mode, feature, i) for i in INPUTS]
            lines.append(f'| {feature} | ' + ' | '.join(cells) + ' |')
        lines.append('')
    return '\n'.join(lines)
