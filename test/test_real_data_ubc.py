"""scripts/ubc_racquet.py: torque-free tosses (ratios and axes); the real tosses when present.

The UBC racquet data set states no licence, so it is not shipped: set
``INERTIA_ROS_UBC_REPO`` to a clone of github.com/fbubbar/sci1-t2 to run the real-data test.
"""
from __future__ import annotations

import importlib.util
import json
import os
from pathlib import Path

import numpy as np
import pytest

from conftest import ROOT
from inertia_ros.cli import main
from inertia_ros.core.scene import Scene
from inertia_ros.core.simulation import simulate

SCRIPT = ROOT / 'scripts' / 'ubc_racquet.py'
REAL = Path(os.environ.get('INERTIA_ROS_UBC_REPO', '/nonexistent'))
#: A racquet-like body [kg m^2] (phone axes): intermediate x, handle y, string normal z; a
#: near-lamina (x + y just above z: the pendulum truth 18.8 + 1.391 < 20.7 is not physical).
BODY = [19.35e-3, 1.45e-3, 20.7e-3]


def _load():
    spec = importlib.util.spec_from_file_location('ubc_racquet', SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    assert spec.loader is not None
    spec.loader.exec_module(mod)
    return mod


def _toss(seed: int, duration: float = 1.5):
    """A simulated toss about the intermediate axis (100 Hz phone gyro, 0.01 rad/s noise)."""
    sc = Scene.from_dict({'duration': duration, 'body': {'inertia': [*BODY, 0.0, 0.0, 0.0]},
                          'initial_omega': [12.0, 0.3, 0.4], 'torque': [],
                          'gyro': {'rate': 100.0, 'noise_std': 0.01}})
    return simulate(sc, seed)


def test_simulated_toss_gives_the_ratios_and_axes():
    """Torque-free toss: Ix/Iz within 0.2 % and Iy/Iz within 2 % of the simulated body's
    (20 seeds: scatter 0.02 % and 0.3 %), the principal axes within 2 deg of the phone axes.

    The ratio sigma's calibration over seeds is test_torque_free_calibration's (RMS z 1.0 on
    these tosses since the covariance carries the gyroscopic noise walk; it was 1.9-2.0).
    """
    mod = _load()
    r = _toss(3)
    row = mod.toss_ratios(r.t_gyro, r.omega, 'auto')
    assert row['status'] == 'scale_unobservable'
    want = np.array([BODY[0] / BODY[2], BODY[1] / BODY[2]])
    got = np.array(row['ratios'])
    assert np.all(np.abs(got / want - 1) < [0.002, 0.02]), (got, want)
    assert np.all(np.array(row['ratios_std']) > 0)
    # the error within 5 sigma (the defect rule)
    assert np.all(np.abs(got - want) < 5 * np.array(row['ratios_std'])), (got, row)
    assert max(row['axis_angle_deg']) < 2.0


def _fake_clone(root: Path) -> None:
    """A clone-shaped directory: one phyphox run with two labelled windows."""
    run = root / 'data' / 'round9' / 'Gyroscope rotation rate 2025-01-01 10-00-00'
    (run / 'meta').mkdir(parents=True)
    parts, t0 = [], 0.0
    for seed in (1, 2):
        r = _toss(seed)
        parts.append(np.column_stack([r.t_gyro + t0, r.omega,
                                      np.linalg.norm(r.omega, axis=1)]))
        t0 += float(r.t_gyro[-1]) + 2.0
    d = np.vstack(parts)
    np.savetxt(run / 'Raw Data.csv', d, delimiter=',', comments='',
               header='Time (s),Gyroscope x (rad/s),Gyroscope y (rad/s),'
                      'Gyroscope z (rad/s),Absolute (rad/s)')
    (run / 'meta' / 'segments.csv').write_text(
        'segment,start,end,keep,comment\n'
        f'0,0.0,{parts[0][-1, 0]},,Intermediate axis rotation\n'
        f'1,{parts[1][0, 0]},{parts[1][-1, 0]},,not a trial\n')


def test_clone_to_mcap_to_cli_and_bench(tmp_path: Path, capsys: pytest.CaptureFixture):
    """A clone-shaped copy -> convert (MCAP per window) -> ``estimate --torque-topic none``
    gives the ratios; ``bench`` keeps only the intermediate-axis tosses."""
    mod = _load()
    _fake_clone(tmp_path / 'clone')
    out = tmp_path / 'mcap'
    assert mod.main(['convert', '--repo', str(tmp_path / 'clone'), '--out', str(out)]) == 0
    idx = json.loads((out / 'index.json').read_text())
    assert len(idx['segments']) == 2
    capsys.readouterr()
    code = main(['estimate', str(out / idx['segments'][0]['mcap']), '--torque-topic', 'none',
                 '--format', 'json', '--no-progress'])
    rep, err = capsys.readouterr()
    assert code == 0, err
    d = json.loads(rep)
    assert d['status'] == 'scale_unobservable'
    r = np.diag(np.array(d['ratios']))
    assert r[1] / r[2] == pytest.approx(BODY[1] / BODY[2], rel=0.03)
    res = tmp_path / 'r.json'
    assert mod.main(['bench', '--repo', str(tmp_path / 'clone'), '--out', str(res)]) == 0
    rows = json.loads(res.read_text())
    assert [r['comment'] for r in rows] == ['Intermediate axis rotation']


@pytest.mark.skipif(not (REAL / 'data').is_dir(), reason='UBC racquet tosses absent (not '
                    'shipped: no licence; set INERTIA_ROS_UBC_REPO); see '
                    'docs/real_data_tudelft.md')
def test_real_tosses_ratios_and_axes(tmp_path: Path) -> None:
    """The real tosses: >= 100 with ratios; median Iy/Iz and Ix/Iz within 1 sigma of the
    pendulum truth; principal axes within 5 deg of the phone axes (median); the tosses'
    robust scatter about their median within [0.5, 1.5]x their median stated sigma (issue 27
    asks [0.5, 2]; it was 2.1x before the covariance carried the gyroscopic noise walk;
    measured 1.05, 1.07 on 2026-11-27)."""
    mod = _load()
    res = tmp_path / 'r.json'
    assert mod.main(['bench', '--repo', str(REAL), '--out', str(res)]) == 0
    rows = [r for r in json.loads(res.read_text()) if 'ratios' in r]
    assert len(rows) >= 100
    med = np.median([r['ratios'] for r in rows], axis=0)
    tr, ts = mod.truth_ratios()
    assert np.all(np.abs(med - tr) <= ts)
    assert np.all(np.median([r['axis_angle_deg'] for r in rows], axis=0) < 5.0)
    R = np.array([r['ratios'] for r in rows])
    mad = 1.4826 * np.median(np.abs(R - np.median(R, axis=0)), axis=0)
    sig = np.median([r['ratios_std'] for r in rows], axis=0)
    assert np.all((mad >= 0.5 * sig) & (mad <= 1.5 * sig)), mad / sig
