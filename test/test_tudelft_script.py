"""scripts/tudelft_throw.py on a synthetic blackbox CSV (the real data may not be shipped)."""
from __future__ import annotations

import importlib.util
import json
import math
import os
from pathlib import Path

import numpy as np
import pytest
from flywheel_throw import flywheel_throw

from conftest import ROOT
from inertia_ros.cli import main

SCRIPT = ROOT / 'scripts' / 'tudelft_throw.py'
#: ``index.json`` of the user's converted TU Delft throws (set to run the real-data test).
REAL = Path(os.environ.get('INERTIA_ROS_TUDELFT_INDEX', '/nonexistent/index.json'))


def _load():
    spec = importlib.util.spec_from_file_location('tudelft_throw', SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    assert spec.loader is not None
    spec.loader.exec_module(mod)
    return mod


def _throw(tmp_path: Path, coupling: np.ndarray | None = None) -> tuple[Path, np.ndarray]:
    """A simulated throw written as a raw blackbox CSV in the authors' units and axes
    (``coupling`` (3, 3): the gyro reads ``coupling @ w``)."""
    r = flywheel_throw(0.5, 60.0)
    w = r.omega if coupling is None else r.omega @ coupling.T   # body frame [rad/s]
    g = np.column_stack([w[:, 1], -w[:, 0], w[:, 2]]) * 16.384 * 180.0 / math.pi
    erpm = r.wheel_speed[:, 0] / (100.0 / 7 * 2 * math.pi / 60)
    t_us = np.round(r.t_gyro * 1e6) + 5_000_000
    p = tmp_path / 'LOG00001.csv'
    cols = np.column_stack([t_us, g, np.zeros((len(t_us), 3)), erpm])
    np.savetxt(p, cols, delimiter=',', comments='',
               header='time (us),gyroADC[0],gyroADC[1],gyroADC[2],accSmooth[0],accSmooth[1],'
                      'accSmooth[2],erpm[0]')
    return p, r.inertia


def test_blackbox_csv_to_mcap_to_estimate(tmp_path: Path,
                                          capsys: pytest.CaptureFixture) -> None:
    """Raw blackbox CSV -> convert (axes, units, 14-pole eRPM) -> MCAP + flywheel.yaml ->
    ``estimate --wheels``: the simulated tensor back within 1 % (the eRPM rounding is not
    modelled here, the float CSV keeps it exact)."""
    mod = _load()
    csv, truth = _throw(tmp_path)
    s = mod.read_throw_csv(csv)
    assert s['t'][0] == 0.0 and s['w'].shape == (len(s['t']), 3)
    out = tmp_path / 'mcap'
    assert mod.main(['convert', str(csv), '--out', str(out), '--flywheel-inertia', '1.7e-6']) \
        == 0
    capsys.readouterr()
    code = main(['estimate', str(out / 'LOG00001.mcap'), '--wheels', str(out / 'flywheel.yaml'),
                 '--model', 'full', '--torque-bias', 'off', '--format', 'json',
                 '--no-progress'])
    outp, err = capsys.readouterr()
    assert code == 0, err
    rep = json.loads(outp)
    est = np.array(rep['inertia'])
    assert np.linalg.norm(est - truth) / np.linalg.norm(truth) < 0.01, rep['status']


@pytest.mark.skipif(not REAL.is_file(), reason='TU Delft recordings absent (not shipped: no '
                    'licence; set INERTIA_ROS_TUDELFT_INDEX); see docs/BENCHMARKS.md')
def test_real_throws_no_silent_failure(tmp_path: Path) -> None:
    """On the real recordings (when the user has them): no status ok with eps > 10 %."""
    mod = _load()
    res = tmp_path / 'r.json'
    mod.main(['bench', '--csv-root', str(REAL.parent), '--index', str(REAL), '--method',
              'integral', '--out', str(res)])
    rows = json.loads(res.read_text())
    assert len(rows) >= 40
    assert not [r for r in rows if r['status'] == 'ok' and r.get('eps', 0) > 0.10]


def _index(tmp_path: Path, csv: Path, truth: np.ndarray, J: float = 1.7e-6) -> Path:
    """An index.json for one simulated throw: a massless-offset device with zero tensor, so
    the object's tensor is the whole body's ``I - J 1``; fit window from sample 300."""
    n = len(_load().read_throw_csv(csv)['t'])
    idx = {'wheel': {'axis': [0, 0, -1], 'inertia': J},
           'device': {'m': 0.1, 'x': [0.0, 0.0, 0.0], 'I_prime': np.zeros((3, 3)).tolist()},
           'logs': [{'csv': csv.name, 'series': 'final_tests', 'config': 'sim',
                     'throw_start': 0, 'fit_window': [300, n],
                     'truth_object': {'m': 1.0, 'cog': [0, 0, 0],
                                      'I': (truth - J * np.eye(3)).tolist()}}]}
    p = tmp_path / 'index.json'
    p.write_text(json.dumps(idx))
    return p


def test_window_index_crops_and_bench_cli_runs_the_plain_cli(tmp_path: Path,
                                                            capsys: pytest.CaptureFixture):
    """``convert --window-index`` writes only the fit window (J from the index);
    ``bench --cli`` estimates each window through the CLI defaults and scores it: the
    simulated tensor back within 1 %, with the method the CLI chose recorded."""
    mod = _load()
    csv, truth = _throw(tmp_path)
    idx = _index(tmp_path, csv, truth)
    out = tmp_path / 'mcap'
    assert mod.main(['convert', str(csv), '--out', str(out), '--window-index', str(idx)]) == 0
    n = len(mod.read_throw_csv(csv)['t'])
    assert f'{n - 300} samples' in capsys.readouterr().out
    assert 'inertia: 1.7e-06' in (out / 'flywheel.yaml').read_text()
    res = tmp_path / 'r.json'
    assert mod.main(['bench', '--csv-root', str(tmp_path), '--index', str(idx), '--cli',
                     '--draws', '50', '--out', str(res)]) == 0
    row = json.loads(res.read_text())[0]
    assert row['method'] in ('ml', 'integral', 'filtered') and row['eps'] < 0.01, row
    assert len(row['body_std']) == 6 and min(row['body_std']) > 0


def test_bench_removes_a_stated_gyro_coupling_and_passes_the_model(tmp_path: Path) -> None:
    """``bench --gyro-coupling XY,XZ,YZ`` removes a symmetric gyro axis coupling before the
    estimate: a throw read through a 2 %, -1 %, 3 % coupling comes back within 1 % with it
    (several per cent off without); ``--model full`` reaches the CLI; a malformed coupling is
    a one-line usage error (exit 2)."""
    mod = _load()
    M = mod.gyro_coupling_matrix((0.02, -0.01, 0.03))
    assert np.allclose(M, [[1, 0.02, -0.01], [0.02, 1, 0.03], [-0.01, 0.03, 1]])
    csv, truth = _throw(tmp_path, M)
    idx = _index(tmp_path, csv, truth)
    eps = {}
    for name, extra in (('raw', []), ('removed', ['--gyro-coupling', '0.02,-0.01,0.03'])):
        res = tmp_path / f'{name}.json'
        assert mod.main(['bench', '--csv-root', str(tmp_path), '--index', str(idx), '--cli',
                         '--model', 'full', '--draws', '20', '--out', str(res), *extra]) == 0
        row = json.loads(res.read_text())[0]
        assert row['model'].startswith('full'), row
        eps[name] = row['eps']
    assert eps['removed'] < 0.01 < eps['raw'], eps
    with pytest.raises(SystemExit) as exc:
        mod.main(['bench', '--csv-root', str(tmp_path), '--index', str(idx),
                  '--gyro-coupling', '0.01,0.02'])
    assert exc.value.code == 2
