"""URDF and SDF ``<inertial>`` blocks from an estimated inertia tensor.

The estimator identifies the tensor about the centre of mass, expressed in the frame of the
gyro and torque data (the body's link frame).  A URDF ``<inertial>`` says the same with

- ``<origin xyz="cx cy cz" rpy="0 0 0"/>``: the centre of mass in the link frame [m]; a zero
  rotation, so the inertial frame has the link frame's axes;
- ``<mass value="m"/>`` [kg]: rotation data cannot tell it, the caller gives it;
- ``<inertia ixx=.. ixy=.. ixz=.. iyy=.. iyz=.. izz=../>`` [kg m^2]: the matrix entries about
  the centre of mass (URDF, SDF, geometry_msgs/Inertia and this package use the same
  convention: ``ixy`` is the matrix element, not a negated product of inertia).

Numbers are written with Python's shortest round-trip representation, so a URDF parser reads
back exactly the floats given (the tests round-trip through ``urdf_parser_py``).

Functions
---------
:func:`urdf_inertial`  the ``<inertial>`` block (text, to paste into a robot description)
:func:`urdf_document`  a complete one-link URDF document holding that block
:func:`sdf_inertial`   the SDFormat ``<inertial>`` block (``<pose>``, ``<mass>``, ``<inertia>``)
:func:`write_urdf`     write :func:`urdf_document` to a file, never over an existing one
:func:`check_name`     refuse a blank link/robot name or one holding control characters
"""
from __future__ import annotations

import math
import os
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from inertia_ros.core.inertia import as_inertia_matrix, check_physical
from inertia_ros.io.outputs import OutputError, check_output, write_output

__all__ = ['check_name', 'sdf_inertial', 'urdf_document', 'urdf_inertial', 'write_urdf']

#: Attribute order of URDF's <inertia> element (as the URDF documentation lists it).
_URDF_ELEMENTS = (('ixx', 0, 0), ('ixy', 0, 1), ('ixz', 0, 2),
                  ('iyy', 1, 1), ('iyz', 1, 2), ('izz', 2, 2))
_NAMES = np.array([['ixx', 'ixy', 'ixz'], ['ixy', 'iyy', 'iyz'], ['ixz', 'iyz', 'izz']])


def _num(x: float) -> str:
    """Shortest text that parses back to exactly ``x`` (``-0.0`` written as ``0``)."""
    x = float(x)
    return '0' if x == 0.0 else repr(x)


def _validated(inertia: Any, mass: Any, com: Any) -> tuple[np.ndarray, float, np.ndarray]:
    """Check the three inputs; one-line ValueError naming the problem otherwise."""
    arr = np.asarray(inertia.matrix if hasattr(inertia, 'matrix') else inertia, dtype=float)
    if arr.shape == (3, 3) and not np.isfinite(arr).all():
        bad = sorted({str(_NAMES[i, j]) for i, j in zip(*np.nonzero(~np.isfinite(arr)),
                                                         strict=True)})
        raise ValueError(f'inertia: {", ".join(bad)} not finite (not identified by the data?); '
                         'a URDF <inertial> needs the full tensor')
    matrix = as_inertia_matrix(arr, 'inertia')
    check = check_physical(matrix)
    if not check.valid:
        raise ValueError('inertia: not a physical rigid-body tensor (' +
                         '; '.join(check.failures) + ')')
    try:
        m = float(mass)
    except (TypeError, ValueError):
        raise ValueError(f'mass: expected a number [kg], got {mass!r}') from None
    if not (math.isfinite(m) and m > 0.0):
        raise ValueError(f'mass: must be a positive finite number [kg], got {mass!r}')
    c = np.asarray(com, dtype=float)
    if c.shape != (3,) or not np.isfinite(c).all():
        raise ValueError(f'com: expected 3 finite coordinates [m], got {com!r}')
    return matrix, m, c


def urdf_inertial(inertia: Any, mass: float, com: Sequence[float] = (0.0, 0.0, 0.0), *,
                  indent: str = '') -> str:
    """The URDF ``<inertial>`` block of a body.

    Parameters
    ----------
    inertia : array_like, shape (3, 3), or InertiaTensor
        Inertia tensor about the centre of mass, in the link frame [kg m^2]; finite,
        symmetric and physical (positive definite, triangle inequalities).
    mass : float
        Body mass [kg], > 0.
    com : sequence of 3 float, optional
        Centre of mass in the link frame [m]; default the link origin.
    indent : str, optional
        Prefix of every line (to nest the block in a ``<link>``).

    Returns
    -------
    str
        Four lines, ``<inertial>`` ... ``</inertial>``, ending with a newline.

    Raises
    ------
    ValueError
        One line naming the input at fault: a non-finite element (by name, e.g. ``ixy``),
        an asymmetric or non-physical tensor, a mass that is not positive, a bad ``com``.
    """
    matrix, m, c = _validated(inertia, mass, com)
    attrs = ' '.join(f'{name}="{_num(matrix[i, j])}"' for name, i, j in _URDF_ELEMENTS)
    return (f'{indent}<inertial>\n'
            f'{indent}  <origin xyz="{" ".join(_num(v) for v in c)}" rpy="0 0 0"/>\n'
            f'{indent}  <mass value="{_num(m)}"/>\n'
            f'{indent}  <inertia {attrs}/>\n'
            f'{indent}</inertial>\n')


def _not_xml(ch: str) -> bool:
    """True for a character XML 1.0 cannot hold or a control character (C0, DEL, C1)."""
    o = ord(ch)
    return (o < 0x20 or 0x7F <= o <= 0x9F or 0xD800 <= o <= 0xDFFF or o in (0xFFFE, 0xFFFF))


#: Longest link or robot name written (URDF readers and RViz labels expect short names).
MAX_NAME_CHARS = 256


def check_name(what: str, name: Any) -> str:
    """A URDF name (link, robot): non-blank text of printable characters.

    Parameters
    ----------
    what : str
        The field named in the error (``'link'``, ``'robot'``).
    name : Any
        The name to check.

    Returns
    -------
    str
        ``name`` unchanged.

    Raises
    ------
    ValueError
        One line: a blank name, one over :data:`MAX_NAME_CHARS` characters, or the first
        control character (``U+0001``, ``U+001F``,
        ``U+FFFE``, a surrogate, ...) it holds, which well-formed XML cannot carry.
    """
    bad = next((ch for ch in name if _not_xml(ch)), None) if isinstance(name, str) else None
    if bad is not None:
        raise ValueError(f'{what}: {name[:40]!r} holds the control character U+{ord(bad):04X}; '
                         'give a name of printable characters')
    if not isinstance(name, str) or not name.strip():
        raise ValueError(f'{what}: expected a non-empty name, got {name!r}')
    if len(name) > MAX_NAME_CHARS:
        raise ValueError(f'{what}: a name of at most {MAX_NAME_CHARS} characters is needed, got '
                         f'{len(name)} ({name[:40]!r}...)')
    return name


def _comment(text: str | None, indent: str) -> str:
    if not text:
        return ''
    # characters XML cannot hold are written as escapes; '--' may not appear in a comment
    text = ''.join(f'\\x{ord(ch):02x}' if _not_xml(ch) and ch != '\n' else ch for ch in text)
    safe = re.sub(r'-{2,}', '-', text.strip()).replace('\n', f'\n{indent}     ')
    return f'{indent}<!-- {safe} -->\n'


def urdf_document(inertia: Any, mass: float, com: Sequence[float] = (0.0, 0.0, 0.0), *,
                  link: str = 'base_link', robot: str = 'inertia_ros_estimate',
                  comment: str | None = None) -> str:
    """A complete URDF document: one ``<link>`` holding :func:`urdf_inertial`'s block.

    Parameters
    ----------
    inertia, mass, com
        As :func:`urdf_inertial`.
    link : str, optional
        Link name (the frame the tensor is expressed in). Default ``'base_link'``.
    robot : str, optional
        Robot name. Default ``'inertia_ros_estimate'``.
    comment : str, optional
        Text of an XML comment placed before the ``<inertial>`` block (provenance: log,
        status, standard errors).

    Returns
    -------
    str
        The document, starting with the XML declaration and ending with a newline.

    Raises
    ------
    ValueError
        As :func:`urdf_inertial`, or a ``link`` / ``robot`` name that is blank or holds a
        control character (:func:`check_name`).
    """
    # lazily: xml.sax.saxutils imports urllib.request (http.client, ssl, email), ~20 ms of
    # every estimate command's start-up that writes no URDF
    from xml.sax.saxutils import quoteattr

    for what, name in (('link', link), ('robot', robot)):
        check_name(what, name)
    block = urdf_inertial(inertia, mass, com, indent='    ')
    return ('<?xml version="1.0"?>\n'
            f'<robot name={quoteattr(robot)}>\n'
            f'  <link name={quoteattr(link)}>\n'
            f'{_comment(comment, "    ")}{block}'
            '  </link>\n'
            '</robot>\n')


def sdf_inertial(inertia: Any, mass: float, com: Sequence[float] = (0.0, 0.0, 0.0), *,
                 indent: str = '') -> str:
    """The SDFormat ``<inertial>`` block of a body (same conventions as URDF).

    ``<pose>cx cy cz 0 0 0</pose>`` places the centre of mass in the link frame [m];
    ``<inertia>`` holds ``<ixx>`` ... ``<izz>`` [kg m^2] about it, in the link's axes.

    Parameters
    ----------
    inertia, mass, com, indent
        As :func:`urdf_inertial`.

    Returns
    -------
    str
        The block, ``<inertial>`` ... ``</inertial>``, ending with a newline.

    Raises
    ------
    ValueError
        As :func:`urdf_inertial`.
    """
    matrix, m, c = _validated(inertia, mass, com)
    lines = [f'{indent}<inertial>',
             f'{indent}  <pose>{" ".join(_num(v) for v in c)} 0 0 0</pose>',
             f'{indent}  <mass>{_num(m)}</mass>',
             f'{indent}  <inertia>']
    lines += [f'{indent}    <{name}>{_num(matrix[i, j])}</{name}>'
              for name, i, j in _URDF_ELEMENTS]
    lines += [f'{indent}  </inertia>', f'{indent}</inertial>']
    return '\n'.join(lines) + '\n'


def write_urdf(path: str | os.PathLike[str], inertia: Any, mass: float,
               com: Sequence[float] = (0.0, 0.0, 0.0), *, link: str = 'base_link',
               robot: str = 'inertia_ros_estimate', comment: str | None = None,
               force: bool = False) -> Path:
    """Write :func:`urdf_document` to ``path``.

    Parameters
    ----------
    path : str or os.PathLike
        Output file; its directory must exist.
    inertia, mass, com, link, robot, comment
        As :func:`urdf_document`.
    force : bool, optional
        Replace an existing file. Default False: an existing file is an error.

    Returns
    -------
    pathlib.Path
        The path written.

    Raises
    ------
    ValueError
        As :func:`urdf_document`; ``path`` exists (without ``force``), is a directory, a
        dangling symbolic link (never followed), or its directory does not exist or cannot be
        written (:func:`inertia_ros.io.outputs.check_output`).
    """
    out = Path(path)
    if out.is_dir():
        raise ValueError(f'{out}: is a directory; give a file name such as {out / "body.urdf"}')
    text = urdf_document(inertia, mass, com, link=link, robot=robot, comment=comment)
    try:
        check_output('urdf', out, force=force)
        write_output(out, text, force=force)
    except OutputError as exc:
        raise ValueError(f"{out}: {str(exc).removeprefix(f'urdf {out}: ')}") from None
    except FileExistsError:
        raise ValueError(f'{out}: exists; choose another name or remove it first') from None
    return out
