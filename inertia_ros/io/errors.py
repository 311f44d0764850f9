"""Errors of the writing side of :mod:`inertia_ros.io`.

:class:`McapWriterError` is raised for misuse of :class:`inertia_ros.io.mcap_writer.McapWriter`
(bad path, topic, type or times) and by
:func:`inertia_ros.io.mcap_writer.write_simulation`.  It is a ``ValueError``, so the command
line reports it as one line without a traceback.  The reading side's errors
(``McapError``, ``LogError``) are defined by :mod:`inertia_ros.io.mcap_records` and
:mod:`inertia_ros.io.logs`.
"""
from __future__ import annotations

__all__ = ['McapWriterError']


class McapWriterError(ValueError):
    """Invalid use of the MCAP writer (bad path, topic, type or times)."""
