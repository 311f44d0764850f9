"""One definition for each rule: the source tree is searched, and batch and online agree.

Issue 12 found the same rule written twice with different numbers (minimum gyro samples 20
against 30, two forms of the torque-free test, the 5x gap rule in three places, the option
vocabularies in three modules, hand copies of the tensor index table, ...).  These tests keep
each rule in its one home:

* vocabularies and thresholds: :mod:`inertia_ros.core.estimation.options`;
* the theta <-> matrix index table: :mod:`inertia_ros.core.tensor`;
* the torque-free test: :func:`inertia_ros.core.estimation.homogeneous.is_torque_free`;
* the noise estimators: :mod:`inertia_ros.core.estimation.noise`;

and check that the batch and the recursive estimators give the same status on either side of
each boundary.

The vocabulary and shared-function checks cover the whole package; the threshold-literal,
default and index-table checks cover ``inertia_ros/core``.
"""
from __future__ import annotations

import ast
import io
import tokenize
from pathlib import Path

import numpy as np
import pytest

from conftest import ROOT
from inertia_ros.core.estimation import (
    RecursiveEstimator,
    align,
    batch,
    estimate,
    homogeneous,
    options,
    recursive,
)

PACKAGE = ROOT / 'inertia_ros'
CORE = PACKAGE / 'core'
VOCABULARIES = {name: getattr(options, name)
                for name in ('METHODS', 'MODELS', 'TORQUE_BIAS', 'HOLDS', 'STATUSES')}
#: The tensor-element index table, as literals (rows, columns, matrix index).
INDEX_TABLES = ([0, 1, 2, 0, 0, 1], [0, 1, 2, 1, 2, 2], [[0, 3, 4], [3, 1, 5], [4, 5, 2]])


def _sources(root: Path) -> list[Path]:
    return sorted(p for p in root.rglob('*.py') if '__pycache__' not in p.parts)


def _literal(node: ast.AST) -> object:
    try:
        value = ast.literal_eval(node)
    except (ValueError, TypeError, SyntaxError, MemoryError, RecursionError):
        return None
    return value


def _code_tokens(path: Path) -> list[tokenize.TokenInfo]:
    """The tokens of a file without comments and strings (docstrings included)."""
    toks = tokenize.generate_tokens(io.StringIO(path.read_text()).readline)
    skip = (tokenize.COMMENT, tokenize.STRING, tokenize.NL, tokenize.NEWLINE, tokenize.INDENT,
            tokenize.DEDENT)                  # (Python 3.11: f-strings are STRING tokens)
    return [t for t in toks if t.type not in skip]


def test_vocabularies_are_defined_once() -> None:
    """No module but options assigns a vocabulary name or spells a vocabulary tuple out."""
    found = []
    for path in _sources(PACKAGE):
        rel = str(path.relative_to(PACKAGE))
        if path == CORE / 'estimation' / 'options.py':
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, (ast.Assign, ast.AnnAssign)):
                targets = node.targets if isinstance(node, ast.Assign) else [node.target]
                for t in targets:
                    name = t.id if isinstance(t, ast.Name) else None
                    if name and name.lstrip('_') in VOCABULARIES | {'RMODELS': ()} \
                            and isinstance(node.value, (ast.Tuple, ast.List)):
                        found.append((rel, name.lstrip('_')))
            if isinstance(node, (ast.Tuple, ast.List)):
                value = _literal(node)
                if isinstance(value, (tuple, list)) and len(value) > 1 \
                        and all(isinstance(v, str) for v in value) \
                        and any(set(value) == set(voc) for voc in VOCABULARIES.values()):
                    found.append((rel, tuple(sorted(value))))
    assert not found, f'vocabularies written outside options.py: {found}'


def test_thresholds_have_no_literal_copies_in_core() -> None:
    """The gap factor, torque-free sigmas and sample minimum appear as numbers only in options.

    A ``5.0`` (or ``5``) multiplied by anything, or a comparison with 20 or 30 (the old minimum
    gyro samples), anywhere else in core is a second definition of a rule.
    """
    bad = []
    for path in _sources(CORE):
        if path.name == 'options.py':
            continue
        toks = _code_tokens(path)
        for i, t in enumerate(toks):
            if t.type != tokenize.NUMBER:
                continue
            before = toks[i - 1].string if i else ''
            after = toks[i + 1].string if i + 1 < len(toks) else ''
            if t.string in ('5.0', '5') and '*' in (before, after):
                bad.append(f'{path.relative_to(ROOT)}:{t.start[0]}: {before} {t.string} {after}')
            if t.string in ('20', '30') and before in ('<', '<=', '>', '>='):
                bad.append(f'{path.relative_to(ROOT)}:{t.start[0]}: {before} {t.string}')
    assert not bad, 'threshold literals outside options.py:\n' + '\n'.join(bad)


def test_selection_defaults_come_from_options() -> None:
    """No core function has a literal default for ``alpha`` or ``identifiability_tol``."""
    bad = []
    for path in _sources(CORE):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                args = node.args.args + node.args.kwonlyargs
                defaults = ([None] * (len(node.args.args) - len(node.args.defaults))
                            + list(node.args.defaults) + list(node.args.kw_defaults))
                for arg, default in zip(args, defaults, strict=True):
                    if arg.arg in ('alpha', 'identifiability_tol') \
                            and isinstance(default, ast.Constant):
                        bad.append(f'{path.relative_to(ROOT)}:{node.lineno} {node.name}')
    assert not bad, 'literal selection defaults: ' + ', '.join(bad)


def test_tensor_index_table_is_written_once_in_core() -> None:
    """The theta <-> matrix index table is spelled out in tensor.py only (no hand copies of
    ``[i[0, 0], i[1, 1], i[2, 2], i[0, 1], i[0, 2], i[1, 2]]`` either)."""
    bad = []
    for path in _sources(CORE):
        if path.name == 'tensor.py' and path.parent == CORE:
            continue
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.List) and _literal(node) in INDEX_TABLES:
                bad.append(f'{path.relative_to(ROOT)}:{node.lineno}: index table')
            if isinstance(node, ast.List) and len(node.elts) == 6 and all(
                    isinstance(e, ast.Subscript) for e in node.elts):
                idx = [_literal(e.slice) for e in node.elts]
                if idx == [(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)]:
                    bad.append(f'{path.relative_to(ROOT)}:{node.lineno}: hand-picked theta')
    assert not bad, '\n'.join(bad)


def test_one_definition_of_each_shared_function() -> None:
    """Each shared rule or estimator is defined in exactly one core module."""
    names = ('is_torque_free', 'noise_std_from_differences', 'median_rows', 'model_basis',
             'momentum_matrix', 'gyroscopic_matrix', 'theta_to_matrix', 'as_times',
             'check_choice', 'conclude', 'fit_two_pass')
    where: dict[str, list[str]] = {n: [] for n in names}
    for path in _sources(PACKAGE):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, (ast.FunctionDef, ast.ClassDef)) and node.name in where:
                where[node.name].append(str(path.relative_to(ROOT)))
    assert {n: len(v) for n, v in where.items()} == dict.fromkeys(names, 1), where


def test_batch_and_recursive_share_the_rules() -> None:
    """Both estimators use the same rule objects, not copies."""
    assert batch.is_torque_free is recursive.is_torque_free is homogeneous.is_torque_free
    assert batch.MIN_GYRO_SAMPLES == recursive.MIN_GYRO_SAMPLES == options.MIN_GYRO_SAMPLES
    # the online gap rule lives in align (OnlineAligner, and the momentum gap rule)
    assert batch.GAP_FACTOR == align.GAP_FACTOR == options.GAP_FACTOR
    assert RecursiveEstimator().policy.alpha == options.ALPHA
    assert RecursiveEstimator().policy.identifiability_tol == options.IDENTIFIABILITY_TOL


def test_torque_free_rule_boundary() -> None:
    """Torque RMS at exactly TORQUE_FREE_SIGMAS noise sigmas is torque-free; above is not."""
    std = np.array([0.01, 0.02, 0.005])
    at = np.full(3, options.TORQUE_FREE_SIGMAS * 0.02)
    assert homogeneous.is_torque_free(at, std)
    assert not homogeneous.is_torque_free(at * (1 + 1e-9), std)
    assert homogeneous.is_torque_free(np.zeros(3), np.zeros(3))


@pytest.fixture(scope='module')
def streams():
    """2 s of the default scene with white gyro noise 2e-3 rad/s and 2 % torque noise."""
    from test_estimation import add_noise, noise_free
    return add_noise(noise_free('default', duration=2.0), 0)


@pytest.mark.parametrize('n', [options.MIN_GYRO_SAMPLES - 1, options.MIN_GYRO_SAMPLES,
                               options.MIN_EQUATIONS, options.MIN_EQUATIONS + 1])
def test_batch_and_recursive_agree_at_the_sample_boundaries(streams, n: int) -> None:
    """With n gyro samples both estimators give the same status (19/20: the sample minimum;
    27/28: the equation minimum, net of the one segment intercept)."""
    tg, w, ts, tau = streams
    b = estimate(tg[:n], w[:n], ts, tau, method='integral', gyro_noise=0.002)
    r = RecursiveEstimator(gyro_noise=0.002)
    r.add_torque(ts, tau)
    r.add_gyro(tg[:n], w[:n])
    e = r.estimate()
    assert b.samples_used == e.samples_used == n
    assert b.status == e.status
    if n <= options.MIN_EQUATIONS:
        assert b.status == 'insufficient_data'
    else:
        assert b.status != 'insufficient_data'


@pytest.mark.parametrize('missing', [3, 5])
def test_batch_and_recursive_agree_on_the_gap_rule(streams, missing: int) -> None:
    """A torque interval of 4 nominal intervals is no gap for either estimator; one of 6 is a
    gap for both (GAP_FACTOR = 5)."""
    tg, w, ts, tau = streams
    keep = np.ones(len(ts), dtype=bool)
    keep[40:40 + missing] = False
    b = estimate(tg, w, ts[keep], tau[keep], method='integral', gyro_noise=0.002)
    r = RecursiveEstimator(gyro_noise=0.002)
    r.add_torque(ts[keep], tau[keep])
    r.add_gyro(tg, w)
    r.estimate()
    batch_gap = any('torque gap' in m for m in b.diagnostics['warnings'])
    is_gap = (missing + 1) > options.GAP_FACTOR
    assert batch_gap == is_gap
    assert (r.gaps > 0) == is_gap
