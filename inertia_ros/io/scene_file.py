"""Scene YAML files -> :class:`~inertia_ros.core.scene.Scene` (schema in ``docs/SCENES.md``).

Parsing happens here, outside the pure core: ``yaml.safe_load`` then ``Scene.from_dict``.
Every problem is one :class:`~inertia_ros.core.scene.SceneError` line naming the file and,
where it applies, the key or the YAML line, e.g.
``config/scenes/x.yaml: gyro.rate: must be a positive number, got 0``.
"""
from __future__ import annotations

import os
from pathlib import Path

import yaml

from inertia_ros.core.scene import Scene, SceneError

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
        If the file cannot be read, is not valid YAML or is not a mapping.
    """
    p = Path(path)
    try:
        text = p.read_text(encoding='utf-8')
    except FileNotFoundError:
        raise SceneError(f'{p}: no such scene file') from None
    except IsADirectoryError:
        raise SceneError(f'{p}: is a directory, expected a scene .yaml file') from None
    except (OSError, UnicodeDecodeError) as exc:
        raise SceneError(f'{p}: cannot read: {exc}') from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, 'problem_mark', None)
        where = f'line {mark.line + 1}: ' if mark is not None else ''
        problem = getattr(exc, 'problem', None) or str(exc).splitlines()[0]
        raise SceneError(f'{p}: {where}invalid YAML: {problem}') from None
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
