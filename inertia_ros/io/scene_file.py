"""Scene YAML files -> :class:`~inertia_ros.core.scene.Scene` (schema in ``docs/SCENES.md``).

Parsing happens here, outside the pure core: the bounded, strict reader of
:mod:`inertia_ros.io.yaml_input`, then ``Scene.from_dict``.
Every problem is one :class:`~inertia_ros.core.scene.SceneError` line naming the file and,
where it applies, the key or the YAML line, e.g.
``config/scenes/x.yaml: gyro.rate: must be a positive number, got 0``.
"""
from __future__ import annotations

import os
from pathlib import Path

from inertia_ros.core.scene import Scene, SceneError
from inertia_ros.io.yaml_input import YamlInputError, read_yaml

__all__ = ['load_scene', 'load_scene_dict']


def load_scene_dict(path: str | os.PathLike[str]) -> dict:
    """Read a scene YAML file into a plain dict (not yet validated).

    Parameters
    ----------
    path : str or pathlib.Path
        The ``.yaml`` file.

    Returns
    -------
    dict
        The top-level mapping.

    Raises
    ------
    SceneError
        If the file cannot be read (not a regular file, over 64 KiB, not UTF-8), is not
        valid YAML (an alias bomb, nesting too deep, a duplicated key) or is not a mapping.
    """
    p = Path(path)
    try:
        data = read_yaml(p, 'scene')
    except YamlInputError as exc:
        raise SceneError(str(exc)) from None
    if not isinstance(data, dict):
        raise SceneError(f'{p}: a scene file must be a mapping of keys, '
                         f'got {type(data).__name__}')
    return data


def load_scene(path: str | os.PathLike[str]) -> Scene:
    """Load and validate a scene YAML file.

    Parameters
    ----------
    path : str or pathlib.Path
        The ``.yaml`` file.

    Returns
    -------
    Scene

    Raises
    ------
    SceneError
        One line ``FILE: KEY: problem`` for unreadable, malformed or invalid scenes.
    """
    data = load_scene_dict(path)
    try:
        return Scene.from_dict(data)
    except SceneError as exc:
        raise SceneError(f'{Path(path)}: {exc}') from None
