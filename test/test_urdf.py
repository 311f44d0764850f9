"""URDF / SDF <inertial> export (inertia_ros.io.urdf), read back by the ROS URDF parser."""
from __future__ import annotations

import json
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from conftest import ROOT
from inertia_ros.core.inertia import nearest_physical
from inertia_ros.io.urdf import sdf_inertial, urdf_document, urdf_inertial, write_urdf

urdf = pytest.importorskip('urdf_parser_py.urdf')  # optional test dependency (urdfdom_py)

#: The estimate of bags/default.mcap (the golden JSON report of test_golden_reports.py).
DEFAULT_ESTIMATE = np.array(json.loads(
    (ROOT / 'test' / 'data' / 'golden' / 'default.json').read_text())['inertia'])


def _parse(text: str):
    """(inertia matrix, mass, origin xyz, origin rpy) of the only link, via urdf_parser_py."""
    robot = urdf.URDF.from_xml_string(text)
    (link,) = robot.links
    inertial = link.inertial
    return (np.array(inertial.inertia.to_matrix()), inertial.mass,
            np.array(inertial.origin.xyz), np.array(inertial.origin.rpy))


def _random_tensors(rng: np.random.Generator, n: int) -> list[np.ndarray]:
    """Physical tensors over many magnitudes: random principal moments and axes."""
    out = []
    for _ in range(n):
        scale = 10.0 ** rng.uniform(-6, 4)
        moments = np.sort(rng.uniform(0.1, 1.0, 3))
        moments[2] = min(moments[2], moments[0] + moments[1])  # triangle inequality
        q, _ = np.linalg.qr(rng.standard_normal((3, 3)))
        out.append(nearest_physical(scale * (q * moments) @ q.T))
    return out


def test_default_bag_estimate_round_trips_exactly():
    """The default log's tensor, mass 10 kg and a CoM offset come back bit for bit (the
    acceptance asks 1e-12), in the link frame: origin = CoM, rpy = 0."""
    com = [0.01, -0.02, 0.125]
    text = urdf_document(DEFAULT_ESTIMATE, 10.0, com, link='body')
    I, mass, xyz, rpy = _parse(text)
    np.testing.assert_array_equal(I, DEFAULT_ESTIMATE)
    assert mass == 10.0
    np.testing.assert_array_equal(xyz, com)
    np.testing.assert_array_equal(rpy, [0.0, 0.0, 0.0])
    assert urdf.URDF.from_xml_string(text).links[0].name == 'body'


def test_random_tensors_round_trip_exactly():
    """Seeded random physical tensors from 1e-6 to 1e4 kg m^2 and random masses/CoMs round
    trip exactly (shortest repr of each float)."""
    rng = np.random.default_rng(17)
    for I in _random_tensors(rng, 200):
        mass = float(10.0 ** rng.uniform(-3, 3))
        com = rng.normal(0.0, 0.5, 3)
        got_I, got_mass, got_xyz, _ = _parse(urdf_document(I, mass, com))
        np.testing.assert_array_equal(got_I, I)
        assert got_mass == mass
        np.testing.assert_array_equal(got_xyz, com)


def test_block_layout_and_defaults():
    """The block nests in a link with the given indent; the default CoM is the link origin and
    off-diagonal elements are the matrix entries (a negative ixy stays negative)."""
    I = np.array([[2.0, -0.25, 0.0], [-0.25, 3.0, 0.0], [0.0, 0.0, 4.0]])
    block = urdf_inertial(I, 1.5, indent='  ')
    assert block.splitlines() == [
        '  <inertial>',
        '    <origin xyz="0 0 0" rpy="0 0 0"/>',
        '    <mass value="1.5"/>',
        '    <inertia ixx="2.0" ixy="-0.25" ixz="0" iyy="3.0" iyz="0" izz="4.0"/>',
        '  </inertial>']
    assert urdf_document(I, 1.5).splitlines()[1:3] == [
        '<robot name="inertia_ros_estimate">', '  <link name="base_link">']


def test_comment_and_names_are_escaped():
    """A provenance comment with '--' and names with XML metacharacters stay well-formed."""
    text = urdf_document(DEFAULT_ESTIMATE, 2.0, link='a&b "c"', robot='r<1>',
                         comment='bags/default.mcap -- status ok\nstd 1e-3')
    root = ET.fromstring(text)
    assert root.get('name') == 'r<1>'
    assert root.find('link').get('name') == 'a&b "c"'
    assert '<!-- bags/default.mcap - status ok' in text
    np.testing.assert_array_equal(_parse(text)[0], DEFAULT_ESTIMATE)


def test_sdf_block_round_trips():
    """The SDFormat block holds <pose> (CoM, zero rotation), <mass> and the six elements."""
    com = [0.5, 0.0, -0.25]
    el = ET.fromstring(sdf_inertial(DEFAULT_ESTIMATE, 3.0, com))
    assert [float(v) for v in el.findtext('pose').split()] == [*com, 0.0, 0.0, 0.0]
    assert float(el.findtext('mass')) == 3.0
    got = {c.tag: float(c.text) for c in el.find('inertia')}
    names = {'ixx': (0, 0), 'iyy': (1, 1), 'izz': (2, 2), 'ixy': (0, 1), 'ixz': (0, 2),
             'iyz': (1, 2)}
    assert got == {k: DEFAULT_ESTIMATE[ij] for k, ij in names.items()}


@pytest.mark.parametrize('inertia, mass, com, match', [
    (np.diag([1.0, 1.0, np.nan]), 1.0, (0, 0, 0), r'^inertia: izz not finite'),
    ([[1, np.nan, 0], [np.nan, 1, 0], [0, 0, 1]], 1.0, (0, 0, 0), r'^inertia: ixy not finite'),
    (np.diag([1.0, 1.0, 3.0]), 1.0, (0, 0, 0), r'^inertia: not a physical'),
    (np.diag([1.0, -1.0, 1.0]), 1.0, (0, 0, 0), r'^inertia: not a physical'),
    (np.ones((2, 2)), 1.0, (0, 0, 0), r'^inertia: expected shape \(3, 3\)'),
    (np.eye(3), 0.0, (0, 0, 0), r'^mass: must be a positive'),
    (np.eye(3), float('inf'), (0, 0, 0), r'^mass: must be a positive'),
    (np.eye(3), 'heavy', (0, 0, 0), r'^mass: expected a number'),
    (np.eye(3), 1.0, (0, 0), r'^com: expected 3 finite'),
    (np.eye(3), 1.0, (0, 0, np.nan), r'^com: expected 3 finite'),
])
def test_bad_input_is_one_line(inertia, mass, com, match):
    """Each bad input is a one-line ValueError naming the input (and the element)."""
    with pytest.raises(ValueError, match=match) as info:
        urdf_inertial(inertia, mass, com)
    assert '\n' not in str(info.value)


def test_write_urdf_never_overwrites(tmp_path):
    """write_urdf writes the document, refuses an existing file (unless force), a directory
    and a missing parent directory."""
    out = write_urdf(tmp_path / 'body.urdf', DEFAULT_ESTIMATE, 10.0, (0.0, 0.0, 0.1))
    np.testing.assert_array_equal(_parse(out.read_text())[0], DEFAULT_ESTIMATE)
    with pytest.raises(ValueError, match='exists'):
        write_urdf(out, np.eye(3), 1.0)
    np.testing.assert_array_equal(_parse(out.read_text())[0], DEFAULT_ESTIMATE)
    write_urdf(out, np.eye(3), 1.0, force=True)
    np.testing.assert_array_equal(_parse(out.read_text())[0], np.eye(3))
    with pytest.raises(ValueError, match='is a directory'):
        write_urdf(tmp_path, np.eye(3), 1.0)
    with pytest.raises(ValueError, match='does not exist'):
        write_urdf(tmp_path / 'no' / 'x.urdf', np.eye(3), 1.0)


def test_estimate_cli_writes_the_urdf(tmp_path, capsys):
    """``estimate bags/default.mcap --urdf out.urdf --mass 10`` round-trips the reported tensor
    (to 1e-12); without --mass, or onto an existing file, one line and exit 2."""
    from inertia_ros.cli import main

    bag = ROOT / 'bags' / 'default.mcap'
    if not bag.exists():
        pytest.skip('bags/default.mcap absent')
    out = tmp_path / 'out.urdf'
    assert main(['estimate', str(bag), '--format', 'json', '--no-progress', '--urdf', str(out),
                 '--mass', '10', '--com', '0', '0', '0.1', '--link', 'body']) == 0
    report = json.loads(capsys.readouterr().out)
    I, mass, xyz, _ = _parse(out.read_text())
    np.testing.assert_allclose(I, report['inertia'], rtol=1e-12, atol=0)
    assert mass == 10.0
    np.testing.assert_array_equal(xyz, [0.0, 0.0, 0.1])
    before = out.read_bytes()
    for extra in (['--mass', '10'], []):
        assert main(['estimate', str(bag), '--no-progress', '--urdf', str(out), *extra]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and '--urdf' in err[0]
    assert out.read_bytes() == before
