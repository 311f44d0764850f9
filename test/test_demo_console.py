"""The demo's console and plot agree, and ``make`` names a missing Python (issue 29 item 10).

The live table prints a row only when it changed, shows the six tensor elements the PNG
plots, and normalises errors by trace/3 of the truth as ``estimate --plot`` does (labelled
in the header, the final line and the PNG).  ``make demo PYTHON=/nonexistent/python3.11``
says in one line that the interpreter is missing and how to give another one.
"""
from __future__ import annotations

import shutil
import subprocess

import numpy as np
import pytest

from conftest import ROOT
from inertia_ros.cli import demo

TRUTH = np.array([[1.0, 0.1, 0.0], [0.1, 2.0, 0.0], [0.0, 0.0, 3.0]])  # trace/3 = 2


def _printed(table, run, times):
    out = []
    for _ in range(times):
        out += table.rows(run)
    return out


def test_table_prints_a_row_only_when_something_changed():
    """Four polls before any estimate and three after the last one print one row each; a
    change of status or estimate prints a new row; the truth is printed once, as a row."""
    run, table = demo._Run(), demo._Table()
    assert len(_printed(table, run, 4)) == 1                      # 'waiting', once
    run.truth.append((0, TRUTH))
    run.status = 'insufficient_data'
    rows = _printed(table, run, 4)
    assert len(rows) == 2 and rows[0].split()[0] == 'truth'
    assert 'insufficient_data' in rows[1]
    est = TRUTH.copy()
    est[0, 0] += 0.02
    run.est.append((5, est))
    run.status = 'ok'
    assert len(_printed(table, run, 3)) == 1
    run.est.append((6, est + 0.001 * np.eye(3)))
    assert len(_printed(table, run, 3)) == 1


def test_table_shows_the_plotted_elements_and_the_labelled_error():
    """The row holds the six elements in the PNG's order (ixx iyy izz ixy ixz iyz); the error
    is max |I_est - I_true| / (trace/3) (1.00 % here; by I3 it would be 0.67 %) and the
    largest element error in sigmas (2.0)."""
    header = demo._table_header()
    names = [n for _, n in demo.ELEMENTS]
    assert header.split()[3:9] == names and 'trace/3' in header
    est = TRUTH.copy()
    est[0, 0] += 0.02
    run = demo._Run(truth=[(0, TRUTH)], est=[(5, est)], status='ok',
                    est_std=[(5, np.full(6, 0.01))])
    row = demo._Table().rows(run)[-1].split()
    np.testing.assert_allclose([float(x) for x in row[2:8]],
                               [est[i, j] for (i, j), _ in demo.ELEMENTS], rtol=1e-4)
    assert row[8] == '1.00%' and float(row[9]) == pytest.approx(2.0)
    final = demo._final(run)
    assert 'max|I_est - I_true| / (trace/3 of the truth) = 1.000%' in final


def test_png_labels_the_same_normalisation(tmp_path, monkeypatch):
    """The PNG's error axis is labelled with the table's normaliser."""
    import matplotlib.axes

    labels = []
    monkeypatch.setattr(matplotlib.axes.Axes, 'set_ylabel',
                        lambda self, text, *a, **k: labels.append(text))
    est = TRUTH.copy()
    run = demo._Run(truth=[(0, TRUTH)], est=[(5, est), (10**9, est)], status='ok',
                    est_std=[(5, np.full(6, 0.01)), (10**9, np.full(6, 0.01))])
    demo._plot(tmp_path / 'x.png', run, 'unit')
    assert any('trace/3' in text for text in labels), labels


@pytest.mark.skipif(shutil.which('make') is None, reason='needs make')
def test_make_names_a_missing_python(tmp_path):
    """`make demo PYTHON=/nonexistent/python3.11` on a fresh venv: exit 2, one stderr line
    naming the interpreter and the fix, no '/bin/sh: ... not found'; nothing created."""
    venv = tmp_path / 'venv'
    proc = subprocess.run(['make', '--no-print-directory', 'demo',
                           'PYTHON=/nonexistent/python3.11', f'VENV={venv}'], cwd=ROOT,
                          capture_output=True, text=True, timeout=60, check=False)
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2 and len(lines) == 1, proc.stderr
    assert ("python '/nonexistent/python3.11' not found; install python3.11 or run "
            'make PYTHON=/path/to/python3.11') in lines[0]
    assert '/bin/sh' not in proc.stderr + proc.stdout and not venv.exists()
