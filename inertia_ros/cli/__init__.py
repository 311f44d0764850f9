"""Command-line interface: ``python -m inertia_ros COMMAND ...``.

Each command lives in its own module exposing ``add_parser(subparsers)`` which registers a
sub-parser whose ``func`` default takes the parsed namespace and returns an exit status.
Errors the user can fix are raised as :class:`UserError` and printed as one line on stderr;
they never surface as a traceback.

Start-up cost: when the command line names a command, only that command's module is imported
(``estimate --help`` never loads ``demo``), and the command modules import nothing heavy at
their top (numpy, scipy and matplotlib are imported inside the functions that use them).
"""
from __future__ import annotations

import argparse
import importlib
import math
import os
import sys
from collections.abc import Callable
from pathlib import Path

from inertia_ros.runtime import keep_freed_memory

#: Command modules, in the order ``--help`` lists them.  A module is listed here only once
#: the command it implements is real.
COMMANDS: tuple[str, ...] = ('simulate', 'estimate', 'fleet', 'bench', 'demo', 'plan')


class UserError(Exception):
    """An error in the user's input: printed as one line, exit status 2."""


#: Longest parse error shown: argparse quotes an invalid value (a 1 MB choice) in full.
MAX_ERROR_CHARS = 400


class Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line on stderr and exit status 2.

    argparse's own format (the usage, then the error) becomes
    ``inertia_ros COMMAND: error: MESSAGE (see --help)``; sub-parsers inherit the class.
    """

    def error(self, message: str) -> None:  # type: ignore[override]
        """Print ``message`` as one line and exit with status 2."""
        name = self.prog.removeprefix('python -m ')
        message = ' '.join(message.split())       # one line, whatever the value held
        if len(message) > MAX_ERROR_CHARS:          # argparse echoes a bad value whole
            cut = MAX_ERROR_CHARS // 2
            message = (f'{message[:cut]} ...[{len(message) - 2 * cut} characters]... '
                       f'{message[-cut:]}')
        self.exit(2, f'{name}: error: {message} (see --help)\n')


def bounded(low: float, high: float, unit: str, integer: bool = False
            ) -> Callable[[str], float]:
    """An argparse ``type=`` accepting a finite number in ``[low, high]``.

    Parameters
    ----------
    low, high : float
        Inclusive range, in ``unit`` (``high`` may be ``math.inf``).
    unit : str
        Unit named in the error (``'s'``, ``'Hz'``, ``''`` for a count).
    integer : bool
        Parse an integer instead of a float.

    Returns
    -------
    callable
        ``parse(text) -> number``; raises ``argparse.ArgumentTypeError`` with the range and
        the unit for anything else (argparse turns it into a one-line error, exit 2).
    """
    kind = 'an integer' if integer else 'a number'
    u = f' {unit}' if unit else ''
    rng = f'>= {low:g}{u}' if high == math.inf else f'within [{low:g}, {high:g}]{u}'

    def parse(text: str) -> float:
        shown = _shown(text)
        try:
            if len(text) > MAX_NUMBER_CHARS:
                raise ValueError(text)
            value = int(text) if integer else float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f'must be {kind} {rng}; got {shown}') from None
        if not (math.isfinite(value) and low <= value <= high):
            raise argparse.ArgumentTypeError(f'must be {rng}; got '
                                             f'{text if len(text) <= 40 else shown}')
        mantissa = text.lower().split('e')[0]
        if value == 0 and any(c in mantissa for c in '123456789'):
            raise argparse.ArgumentTypeError(f'{shown} is too small for a float (it reads as '
                                             f'0); give 0 or a number {rng}')
        return value

    parse.__name__ = kind
    return parse


#: Longest number accepted on the command line [characters].
MAX_NUMBER_CHARS = 64
#: Longest path accepted on the command line [bytes] (Linux PATH_MAX), and path component.
MAX_PATH_BYTES, MAX_NAME_BYTES = 4096, 255


def _shown(text: str, limit: int = 40) -> str:
    """``repr(text)`` cut to ``limit`` characters, for a one-line error."""
    r = repr(text)
    return r if len(r) <= limit else f'{r[:limit - 4]}...\' ({len(text)} characters)'


def path_arg(text: str) -> Path:
    """An argparse ``type=`` for a file or directory path: non-empty, no NUL byte, at most
    :data:`MAX_PATH_BYTES` bytes and :data:`MAX_NAME_BYTES` per component (what the system
    can open); refused at parse time with one line naming the value."""
    raw = os.fsencode(text) if text else b''
    if not text.strip():
        raise argparse.ArgumentTypeError('must be a path, got an empty string')
    if '\0' in text:
        raise argparse.ArgumentTypeError(f'must not contain a NUL byte; got {_shown(text)}')
    longest = max((len(c) for c in raw.split(b'/')), default=0)
    if len(raw) > MAX_PATH_BYTES or longest > MAX_NAME_BYTES:
        raise argparse.ArgumentTypeError(
            f'a path of at most {MAX_PATH_BYTES} bytes ({MAX_NAME_BYTES} per name) is '
            f'needed; got {len(raw)} bytes: {_shown(text)}')
    return Path(text)


def path_text_arg(text: str) -> str:
    """:func:`path_arg`, returning the text itself (for options read as strings)."""
    path_arg(text)
    return text


def name_arg(text: str) -> str:
    """An argparse ``type=`` for a topic or link name: 1 to 256 printable characters without
    spaces."""
    if not text or len(text) > 256 or not text.isprintable() or any(c.isspace() for c in text):
        raise argparse.ArgumentTypeError(f'must be a name of 1 to 256 printable characters '
                                         f'without spaces; got {_shown(text)}')
    return text


def version() -> str:
    """The package version, ``inertia_ros.__version__`` (a test keeps it equal to the
    installed distribution's metadata, which is slower to read at start-up)."""
    from inertia_ros import __version__

    return __version__


class _VersionAction(argparse.Action):
    """``--version``: print ``inertia_ros VERSION`` and exit 0."""

    def __init__(self, option_strings: list[str], dest: str, **kwargs: object) -> None:
        super().__init__(option_strings, dest, nargs=0, default=argparse.SUPPRESS, **kwargs)

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace,
                 values: object, option_string: str | None = None) -> None:
        print(f'inertia_ros {version()}')
        parser.exit(0)


def _command_in(argv: list[str]) -> str | None:
    """The command named by ``argv`` (its first non-option word), if it is one we know."""
    for word in argv:
        if not word.startswith('-'):
            return word if word in COMMANDS else None
    return None


def program_name(argv0: str | None = None) -> str:
    """The name the command line was invoked by, for ``usage:`` and the errors.

    ``python -m inertia_ros`` runs ``inertia_ros/__main__.py``; an installed console script
    (``inertia-ros``) runs under its own name, which the usage then shows.

    Parameters
    ----------
    argv0 : str, optional
        The program path (default ``sys.argv[0]``).
    """
    import os

    argv0 = sys.argv[0] if argv0 is None else argv0
    base = os.path.basename(argv0 or '')
    if not base or base in ('__main__.py', '-c', '-m') or base.startswith('python'):
        return 'python -m inertia_ros'
    return base


def build_parser(only: str | None = None) -> argparse.ArgumentParser:
    """Return the top-level argument parser.

    Parameters
    ----------
    only : str, optional
        Build the full sub-parser of this command alone (the others are registered as bare
        names, so ``--help`` of one command imports no other command's module).  Default:
        every command.
    """
    parser = Parser(
        prog=program_name(),
        description='Estimate a rigid body\'s inertia tensor from gyro and torque streams.')
    parser.add_argument('--version', action=_VersionAction,
                        help='print the package version and exit')
    sub = parser.add_subparsers(dest='command', metavar='COMMAND')
    for name in COMMANDS:
        if only is None or name == only:
            importlib.import_module(f'inertia_ros.cli.{name}').add_parser(sub)
        else:
            sub.add_parser(name, add_help=False)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the command line; return the process exit status."""
    argv = sys.argv[1:] if argv is None else list(argv)
    command = _command_in(argv)
    if command is None and '--version' in argv:     # answered without loading any command
        print(f'inertia_ros {version()}')
        return 0
    parser = build_parser(command)
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:        # --help, --version, or a one-line parse error
        return exc.code if isinstance(exc.code, int) else 0
    if getattr(args, 'func', None) is None:
        parser.print_help(sys.stderr)
        return 2
    keep_freed_memory()               # the estimates' arrays reuse freed heap, no page faults
    try:
        return int(args.func(args) or 0)
    except UserError as exc:
        print(f'inertia_ros {args.command}: error: {exc}', file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f'inertia_ros {args.command}: interrupted', file=sys.stderr)
        return 130
