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
import sys
from collections.abc import Callable

from inertia_ros.runtime import keep_freed_memory

#: Command modules, in the order ``--help`` lists them.  A module is listed here only once
#: the command it implements is real.
COMMANDS: tuple[str, ...] = ('simulate', 'estimate', 'fleet', 'bench', 'demo', 'plan')


class UserError(Exception):
    """An error in the user's input: printed as one line, exit status 2."""


class Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line on stderr and exit status 2.

    argparse's own format (the usage, then the error) becomes
    ``inertia_ros COMMAND: error: MESSAGE (see --help)``; sub-parsers inherit the class.
    """

    def error(self, message: str) -> None:  # type: ignore[override]
        """Print ``message`` as one line and exit with status 2."""
        name = self.prog.removeprefix('python -m ')
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
        try:
            value = int(text) if integer else float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f'must be {kind} {rng}; got {text!r}') from None
        if not (math.isfinite(value) and low <= value <= high):
            raise argparse.ArgumentTypeError(f'must be {rng}; got {text}')
        return value

    parse.__name__ = kind
    return parse


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
        prog='python -m inertia_ros',
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
