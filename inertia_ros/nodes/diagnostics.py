"""The estimator's ``diagnostic_msgs/DiagnosticArray``: levels, names, key/values.

Follows the ``diagnostic_updater`` convention: one ``DiagnosticStatus`` per task, named
``'<node name>: <task>'`` (:func:`status_name`), published on ``/diagnostics`` about once a
second (:data:`DIAGNOSTIC_PERIOD`).  The status carries the estimate in its JSON-contract
form (docs/DESIGN.md) as key/values, and node-level problems (silent stream, refused frame)
raise its level.
"""
from __future__ import annotations

import json
import math
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

from inertia_ros.core.inertia import THETA_NAMES, matrix_to_theta
from inertia_ros.nodes.messages import header

__all__ = ['DIAGNOSTIC_LEVELS', 'DIAGNOSTIC_PERIOD', 'diagnostic_array', 'diagnostic_status',
           'status_name']

#: DiagnosticStatus level for each estimate status: ``ok`` is OK, every other status is WARN
#: with its reason in the message (a start or a reset is ``insufficient_data``, torque-free data
#: ``scale_unobservable``: normal situations, never ERROR).  ERROR is kept for node-level
#: faults (samples refused for their frame, an estimator exception).
DIAGNOSTIC_LEVELS: dict[str, bytes] = {
    'ok': DiagnosticStatus.OK,
    'insufficient_data': DiagnosticStatus.WARN,
    'partially_identifiable': DiagnosticStatus.WARN,
    'model_mismatch': DiagnosticStatus.WARN,
    'scale_unobservable': DiagnosticStatus.WARN,
    'insufficient_excitation': DiagnosticStatus.WARN,
}

#: Period of the diagnostics [s] (diagnostic_updater's default: 1 Hz).
DIAGNOSTIC_PERIOD = 1.0


def status_name(node_name: str, task: str) -> str:
    """``'<node name>: <task>'``, the diagnostic_updater name of a node's task status."""
    return f'{node_name}: {task}'


def _fmt(value: Any) -> str:
    """Render a diagnostic value as the string a KeyValue carries (JSON for containers)."""
    if value is None:
        return 'null'
    if isinstance(value, (bool, np.bool_)):
        return 'true' if value else 'false'
    if isinstance(value, (float, np.floating)):
        v = float(value)
        return 'nan' if math.isnan(v) else f'{v:.6g}'
    if isinstance(value, (int, np.integer, str)):
        return str(value)
    if isinstance(value, np.ndarray):
        value = value.tolist()
    try:
        return json.dumps(value, default=str, allow_nan=True)
    except (TypeError, ValueError):
        return str(value)


def _reason(result: Mapping[str, Any]) -> str:
    diag = result.get('diagnostics') or {}
    for key in ('reason', 'message'):
        if diag.get(key):
            return str(diag[key])
    warnings = diag.get('warnings')
    if warnings:
        return '; '.join(str(w) for w in warnings) if not isinstance(warnings, str) else warnings
    return ''


def _estimate_values(result: Mapping[str, Any], status: str) -> list[tuple[str, Any]]:
    """The contract fields of an estimate as (key, value) pairs, in display order."""
    values: list[tuple[str, Any]] = [('status', status)]
    diag: Mapping[str, Any] = result.get('diagnostics') or {}
    for key in ('model', 'method'):
        if key in result:
            values.append((key, result[key]))
    cond = next((diag[k] for k in ('condition_number', 'condition', 'cond') if k in diag), None)
    values.append(('condition_number', cond))
    std = result.get('inertia_std')
    std_arr = None if std is None else np.asarray(
        [[np.nan if v is None else v for v in row] for row in std], dtype=float)
    std_theta = None if std_arr is None else matrix_to_theta(std_arr, rtol=np.inf,
                                                             check_finite=False)
    for k, el in enumerate(THETA_NAMES):
        values.append((f'std_{el}', None if std_theta is None else std_theta[k]))
    samples = result.get('samples') or {}
    values.append(('samples_used', samples.get('used')))
    values.append(('samples_dropped', samples.get('dropped')))
    for key in ('principal_moments_std', 'principal_ratios', 'principal_ratios_std'):
        if diag.get(key) is not None:
            values.append((key, diag[key]))
    axes_std = diag.get('principal_axes_std')
    if axes_std is not None:      # [deg]: how far each principal axis may be off (1 sigma)
        values.append(('principal_axes_std_deg',
                       [None if v is None else math.degrees(float(v)) for v in axes_std]))
    if 'torque_bias' in result:
        values.append(('torque_bias', result['torque_bias']))
    if 'identifiable' in result:
        values.append(('identifiable', result['identifiable']))
    if result.get('ratios') is not None and status != 'ok':
        values.append(('ratios', result['ratios']))  # what torque-free data still gives
        if result.get('ratios_std') is not None:
            values.append(('ratios_std', result['ratios_std']))
    return values


def diagnostic_status(result: Mapping[str, Any] | None, *, name: str, hardware_id: str = '',
                      extra: Mapping[str, Any] | None = None,
                      problems: Sequence[tuple[bytes, str]] = ()) -> DiagnosticStatus:
    """Build the estimator's ``DiagnosticStatus`` from an estimate in its JSON-contract form.

    Parameters
    ----------
    result : mapping or None
        ``InertiaEstimate.to_dict()`` (docs/DESIGN.md contract: status, inertia_std, model,
        method, samples, diagnostics, ...), or None before any estimate exists (then the
        status is ``insufficient_data``).
    name : str
        ``DiagnosticStatus.name``: ``'<node name>: <task>'`` by the diagnostic_updater
        convention (:func:`status_name`).
    hardware_id : str, optional
        ``DiagnosticStatus.hardware_id`` (the node's name).
    extra : mapping, optional
        Further key/values from the node (counts of received, NaN-dropped and refused
        messages, stream ages [s], ...); values are rendered as strings.
    problems : sequence of (level, message), optional
        Node-level conditions (stream timeout, frame mismatch, ...).  The reported level is
        the worst of the estimate's level and these; their messages are prepended.

    Returns
    -------
    diagnostic_msgs.msg.DiagnosticStatus
        ``level`` from :data:`DIAGNOSTIC_LEVELS`, ``message`` = ``status`` plus the reason,
        ``values``: status, model, method, condition_number, std_<element> [kg m^2],
        samples_used, samples_dropped, torque_bias, every scalar entry of ``diagnostics``,
        then ``extra``.
    """
    if result is None:
        result = {'status': 'insufficient_data', 'diagnostics': {'reason': 'no samples yet'}}
    status = str(result.get('status', 'insufficient_data'))
    if status not in DIAGNOSTIC_LEVELS:
        raise ValueError(f'result status {status!r} is not one of {sorted(DIAGNOSTIC_LEVELS)}')
    level = DIAGNOSTIC_LEVELS[status]
    reason = _reason(result)
    message = status + (f': {reason}' if reason and status != 'ok' else '')
    for p_level, _ in problems:
        level = max(level, p_level)
    if problems:
        message = '; '.join([m for _, m in problems] + [message])

    values = _estimate_values(result, status)
    values.append(('reason', reason))
    diag: Mapping[str, Any] = result.get('diagnostics') or {}
    seen = {k for k, _ in values}
    for key, val in diag.items():
        if key not in seen and isinstance(val, (int, float, str, bool, np.number, np.bool_)):
            values.append((str(key), val))
            seen.add(str(key))
    for key, val in (extra or {}).items():
        values.append((str(key), val))
    return DiagnosticStatus(level=level, name=name, message=message, hardware_id=hardware_id,
                            values=[KeyValue(key=k, value=_fmt(v)) for k, v in values])


def diagnostic_array(statuses: Iterable[DiagnosticStatus], t_ns: int) -> DiagnosticArray:
    """Wrap statuses in a ``diagnostic_msgs/DiagnosticArray`` stamped ``t_ns`` [ns]."""
    return DiagnosticArray(header=header(t_ns, ''), status=list(statuses))
