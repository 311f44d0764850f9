"""Sensor nuisance terms (issue 14 items 3 and 6): the simulator's imperfections and the
estimator's evidence rule.

Each term has a seeded scene where it is present (chosen, value within 3 sigma of the truth)
and the same family of scenes without it (chosen in at most 2 of 20 seeds: >= 90 % not
chosen).  The fits run on reduced records (20 s, 200 Hz gyro, 100 Hz torque) so the file
stays under a minute.
"""
from __future__ import annotations

import copy
import json

import numpy as np
import pytest

from conftest import ROOT
from inertia_ros.cli import main
from inertia_ros.core.estimation import estimate
from inertia_ros.core.estimation.nuisance import fit_nuisance
from inertia_ros.core.estimation.options import ALPHA, NUISANCE_TERMS, check_nuisance
from inertia_ros.core.scene import Scene, SceneError
from inertia_ros.core.simulation import simulate
from inertia_ros.core.tensor import matrix_to_theta

BASE = {'duration': 20.0, 'body': {'inertia': [1.0, 1.2, 0.9, 0.05, -0.03, 0.02]},
        'initial_omega': [0.05, -0.03, 0.02],
        'torque': [{'type': 'multisine', 'amplitude': 0.5, 'f_min': 0.05, 'f_max': 2.0}],
        'command_rate': 100.0, 'gyro': {'rate': 200.0, 'noise_std': 0.002},
        'torque_sensor': {'rate': 100.0, 'noise_rel': 0.02}}
#: Scene changes that put each term in the data, and its true value.
PRESENT = {
    # the gyroscopic term carries the bias: large rate swings make it differ from a
    # constant torque
    'gyro_bias': ({'torque': [{'type': 'multisine', 'amplitude': 3.0, 'f_min': 0.05,
                               'f_max': 1.0}],
                   'gyro': {'bias': [0.02, -0.015, 0.01]}}, [0.02, -0.015, 0.01]),
    'torque_delay': ({'imperfections': {'torque_delay': 0.015}}, 0.015),
    'damping': ({'damping': [0.1, 0.15, 0.08]}, [0.1, 0.15, 0.08]),
    'gyro_lowpass': ({'gyro': {'time_constant': 0.015}}, 0.015),
}


def _scene(**changes) -> Scene:
    d = copy.deepcopy(BASE)
    for k, v in changes.items():
        if isinstance(v, dict):
            d.setdefault(k, {}).update(v)
        else:
            d[k] = v
    return Scene.from_dict(d)


@pytest.mark.parametrize('term', NUISANCE_TERMS)
def test_present_term_is_chosen_and_within_three_sigma(term: str) -> None:
    """The term in the data is chosen; each of its values is within 3 sigma of the truth."""
    changes, truth = PRESENT[term]
    r = simulate(_scene(**changes), seed=1)
    fit, record = fit_nuisance(r.t_gyro, r.omega, r.t_torque, r.torque, 'auto', ALPHA)
    assert term in record['chosen'], record
    assert record['evidence'][term]['p_value'] < ALPHA
    value, sigma = np.atleast_1d(fit.value(term)), np.atleast_1d(fit.sigma(term))
    assert np.all(sigma > 0)
    z = (value - np.atleast_1d(truth)) / sigma
    assert np.all(np.abs(z) < 3.0), (term, value, sigma)


def test_absent_terms_are_not_chosen_in_ninety_percent_of_seeds() -> None:
    """Without any nuisance in the data, each term is chosen in at most 2 of 20 seeds."""
    scene = _scene(duration=12.0)
    counts = dict.fromkeys(NUISANCE_TERMS, 0)
    for seed in range(20):
        r = simulate(scene, seed=seed)
        _, record = fit_nuisance(r.t_gyro, r.omega, r.t_torque, r.torque, 'auto', ALPHA)
        for t in record['chosen']:
            counts[t] += 1
    assert all(c <= 2 for c in counts.values()), counts


def test_estimate_reports_the_choice_and_keeps_sigma_honest() -> None:
    """End to end: a delayed torque stream; the tensor within 4 sigma, sigma widened."""
    r = simulate(_scene(imperfections={'torque_delay': 0.02}), seed=3)
    est = estimate(r.t_gyro, r.omega, r.t_torque, r.torque, method='integral',
                   nuisance='auto')
    rec = est.diagnostics['nuisance']
    assert rec['chosen'] == ['torque_delay']
    assert abs(rec['values']['torque_delay'] - 0.02) < 3 * rec['sigma']['torque_delay']
    assert rec['units']['torque_delay'] == 's'
    z = (matrix_to_theta(est.inertia) - matrix_to_theta(r.inertia)) / np.sqrt(
        np.diag(est.covariance))
    assert np.all(np.abs(z) < 4.0), z
    off = estimate(r.t_gyro, r.omega, r.t_torque, r.torque, method='integral')
    assert 'nuisance' not in off.diagnostics            # the default is off
    assert np.all(np.diag(est.covariance) >= 0.0)


def test_a_list_forces_the_terms() -> None:
    """``nuisance=[...]`` fits exactly those terms, whatever the evidence."""
    r = simulate(_scene(duration=12.0), seed=0)
    est = estimate(r.t_gyro, r.omega, r.t_torque, r.torque, method='integral',
                   nuisance=['damping'])
    rec = est.diagnostics['nuisance']
    assert rec['requested'] == ['damping'] and rec['chosen'] == ['damping']
    assert len(rec['values']['damping']) == 3 and len(rec['sigma']['damping']) == 3
    assert len(rec['theta_std_added']) == 6


def test_torque_free_data_skip_the_fit() -> None:
    """No torque stream: nothing to offset or filter; said so."""
    d = copy.deepcopy(BASE)
    d.pop('torque')
    d['initial_omega'] = [0.3, 0.5, -0.2]
    r = simulate(Scene.from_dict(d), seed=0)
    est = estimate(r.t_gyro, r.omega, np.zeros(0), np.zeros((0, 3)), nuisance='auto')
    assert 'torque-free' in est.diagnostics['nuisance']['skipped']


@pytest.mark.parametrize('stream', ['zeros', 'noise'])
def test_torque_free_found_from_the_torque_stream_skips_the_fit(stream: str) -> None:
    """A torque stream that is zero (the node's ``torque_topic: none`` feeds zeros; a log
    whose torque topic carries zeros, as bags/quadrotor.mcap's) or noise only is torque-free
    data: the capability table's ``runs as nuisance='off'``, said by ``skipped``.  Before,
    the fit ran on the homogeneous equations: with zeros the whitener of its zero residuals
    raised LinAlgError ('Matrix is not positive definite': ``estimate --nuisance auto`` on
    bags/quadrotor.mcap without ``--rotors`` stopped with exit 2, the batch window raised),
    with noise it chose gyro_lowpass (p < 1e-10) on data that have no torque to filter."""
    d = copy.deepcopy(BASE)
    d.pop('torque')
    d['initial_omega'] = [0.3, 0.5, -0.2]
    r = simulate(Scene.from_dict(d), seed=0)
    tau = (np.zeros_like(r.torque) if stream == 'zeros' else
           1e-3 * np.random.default_rng(0).standard_normal(r.torque.shape))
    est = estimate(r.t_gyro, r.omega, r.t_torque, tau, method='integral', nuisance='auto')
    assert est.status == 'scale_unobservable', est.status
    record = est.diagnostics['nuisance']
    assert 'torque-free' in record['skipped'] and record['chosen'] == [], record


@pytest.mark.parametrize('value, expected', [
    ('auto', 'auto'), ('off', 'off'), ('damping,gyro_bias', ('gyro_bias', 'damping')),
    (['gyro_lowpass'], ('gyro_lowpass',))])
def test_check_nuisance_accepts(value, expected) -> None:
    assert check_nuisance(value) == expected


@pytest.mark.parametrize('value', ['on', ['bias'], [], 3, 'gyro_bias,wind'])
def test_check_nuisance_refuses_with_one_line(value) -> None:
    with pytest.raises(ValueError, match=r'^nuisance: ') as info:
        check_nuisance(value)
    assert '\n' not in str(info.value)


# ------------------------------------------------------------------------------------------
# simulator imperfections
# ------------------------------------------------------------------------------------------

def test_gyro_lowpass_is_a_first_order_filter() -> None:
    """A spin-up under a torque step: the reading lags the truth by T_g on the ramp."""
    d = {'duration': 2.0, 'body': {'inertia': [1.0, 1.0, 1.0, 0.0, 0.0, 0.0]},
         'torque': [{'type': 'constant', 'amplitude': [0.1, 0.0, 0.0], 'axes': ['x']}],
         'gyro': {'rate': 1000.0, 'time_constant': 0.05}}
    r = simulate(Scene.from_dict(d))
    late = r.t_gyro > 1.0                          # after the 20 T_g transient
    lag = (r.omega_true[late, 0] - r.omega[late, 0]) / 0.1   # ramp slope 0.1 rad/s^2
    np.testing.assert_allclose(lag, 0.05, rtol=1e-6)


def test_gyro_quantisation() -> None:
    """Every reading is a multiple of the LSB, within half an LSB of the truth."""
    d = copy.deepcopy(BASE)
    d['duration'] = 2.0
    d['gyro'] = {'rate': 200.0, 'lsb': 0.001}
    r = simulate(Scene.from_dict(d))
    np.testing.assert_allclose(r.omega / 0.001, np.round(r.omega / 0.001), atol=1e-9)
    assert np.max(np.abs(r.omega - r.omega_true)) <= 0.0005 + 1e-12


def test_damping_decays_a_free_spin() -> None:
    """A sphere spinning under damping only: w(t) = w0 exp(-D t / I) per axis."""
    d = {'duration': 3.0, 'body': {'inertia': [2.0, 2.0, 2.0, 0.0, 0.0, 0.0]},
         'initial_omega': [1.0, -2.0, 0.5], 'damping': [0.2, 0.4, 0.0]}
    r = simulate(Scene.from_dict(d))
    expect = np.array([1.0, -2.0, 0.5]) * np.exp(-np.outer(r.t_gyro, [0.1, 0.2, 0.0]))
    np.testing.assert_allclose(r.omega_true, expect, rtol=1e-8, atol=1e-10)


def test_zero_damping_keeps_the_simulation_bit_identical() -> None:
    """``damping: [0, 0, 0]`` and no key give the same streams."""
    a = simulate(_scene(duration=3.0), seed=4)
    b = simulate(_scene(duration=3.0, damping=[0.0, 0.0, 0.0]), seed=4)
    assert np.array_equal(a.omega, b.omega) and np.array_equal(a.torque, b.torque)


@pytest.mark.parametrize('changes, message', [
    ({'gyro': {'time_constant': -0.01}}, r'^gyro\.time_constant: must be >= 0'),
    ({'gyro': {'time_constant': 2.0}}, r'^gyro\.time_constant: .*at most 1 s'),
    ({'gyro': {'lsb': 'fine'}}, r'^gyro\.lsb: must be a number'),
    ({'damping': [0.1, -0.1, 0.0]}, r'^damping\[1\]: must be >= 0'),
    ({'damping': 0.1}, r'^damping: must be a list of 3 numbers'),
])
def test_new_scene_keys_are_validated(changes, message) -> None:
    with pytest.raises(SceneError, match=message) as info:
        _scene(**changes)
    assert '\n' not in str(info.value)


# ------------------------------------------------------------------------------------------
# command line
# ------------------------------------------------------------------------------------------

def test_cli_nuisance_on_the_delay_sample(capsys: pytest.CaptureFixture) -> None:
    """``estimate bags/torque_delay.mcap --nuisance auto``: the offset found, in JSON and text."""
    bag = str(ROOT / 'bags' / 'torque_delay.mcap')
    assert main(['estimate', bag, '--nuisance', 'auto', '--format', 'json',
                 '--no-progress']) == 0
    rep = json.loads(capsys.readouterr().out)
    rec = rep['diagnostics']['nuisance']
    assert rep['status'] == 'ok' and rec['chosen'] == ['torque_delay']
    assert abs(rec['values']['torque_delay'] - 0.015) < 3 * rec['sigma']['torque_delay']
    assert main(['estimate', bag, '--nuisance', 'torque_delay', '--no-progress']) == 0
    text = capsys.readouterr().out
    assert 'nuisance: torque_delay 0.01' in text and ' s' in text


def test_cli_nuisance_on_the_lowpass_sample(capsys: pytest.CaptureFixture) -> None:
    """``estimate bags/gyro_lowpass.mcap --nuisance auto`` (issue 29 item 6): the low-pass is
    chosen, not a torque delay of -16.5 ms (which left ixx/iyy/izz 2.5-2.8 sigma and 0.24 %
    off); its time constant within 3 sigma of the scene's 15 ms, every moment within 2 sigma
    and 0.2 % of the truth, the whole-record comparison in the record."""
    bag = str(ROOT / 'bags' / 'gyro_lowpass.mcap')
    assert main(['estimate', bag, '--nuisance', 'auto', '--format', 'json',
                 '--no-progress']) == 0
    rep = json.loads(capsys.readouterr().out)
    rec = rep['diagnostics']['nuisance']
    assert rep['status'] == 'ok' and rec['chosen'] == ['gyro_lowpass'], rec
    assert abs(rec['values']['gyro_lowpass'] - 0.015) < 3 * rec['sigma']['gyro_lowpass']
    ranked = rec['ranked_by_residual_excess'][0]
    assert ranked['gyro_lowpass'] < ranked['torque_delay']
    truth = np.array([1.0, 1.2, 0.9])
    got = np.diag(np.array(rep['inertia']))
    std = np.diag(np.array(rep['inertia_std']))
    assert np.all(np.abs(got - truth) <= 2.0 * std), (got - truth) / std
    assert np.all(np.abs(got - truth) <= 0.002 * truth)


def test_lowpass_and_delay_told_apart_over_seeds() -> None:
    """The two terms act alike (both shift the torque against the rate by ~T_g); the interval
    test alone took a 15 ms low-pass for a torque delay in 4 of the first 6 seeds.  With the
    whole-record comparison: the true term in at least 8 of 9 records (6 low-pass, 3 delay
    scenes); where the twin is chosen, the two residual excesses are within 0.5 % of each
    other (a tie these data cannot break: low-pass seed 5 since the no-bias segment length,
    1.0439 against 1.0457) and every element stays within 3 sigma of the truth."""
    wrong = 0
    for term, seeds in (('gyro_lowpass', range(1, 7)), ('torque_delay', range(1, 4))):
        for seed in seeds:
            r = simulate(_scene(**PRESENT[term][0]), seed=seed)
            est = estimate(r.t_gyro, r.omega, r.t_torque, r.torque, nuisance='auto')
            rec = est.diagnostics['nuisance']
            if rec['chosen'] == [term]:
                continue
            wrong += 1
            ranked = rec['ranked_by_residual_excess'][0]
            excess = [ranked[t] for t in ('gyro_lowpass', 'torque_delay')]
            assert rec['chosen'] in (['gyro_lowpass'], ['torque_delay']), (term, seed, rec)
            assert abs(excess[0] - excess[1]) <= 0.005 * min(excess), (term, seed, ranked)
            z = (est.inertia - r.inertia) / est.inertia_std
            assert np.all(np.abs(z) < 3.0), (term, seed, z)
    assert wrong <= 1, wrong


def test_cli_refuses_an_unknown_term(capsys: pytest.CaptureFixture) -> None:
    """A bad ``--nuisance`` value: exit 2, one line naming the option."""
    assert main(['estimate', str(ROOT / 'bags' / 'default.mcap'), '--nuisance', 'wind']) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and '--nuisance' in err[0] and 'wind' in err[0]
