"""Command-line interface: ``python -m inertia_ros COMMAND ...``.

Each command lives in its own module exposing ``add_parser(subparsers)`` which registers a
sub-parser whose ``func`` default takes the parsed namespace and returns an exit status.
Errors the user can fix are raised as :class:`UserError` and printed as one line on stderr;
they never surface as a traceback.
"""
from __future__ import annotations

import argparse
import importlib
import sys

#: Command modules, in the order ``--help`` lists them.  A module is listed here only once
#: the command it implements is real.
COMMANDS: tuple[str, ...] = ('simulate', 'estimate', 'fleet', 'bench', 'demo')


class UserError(Exception):
    """An error in the user's input: printed as one line, exit status 2."""


def build_parser() -> argparse.ArgumentParser:
    """Return the top-level argument parser with every registered command."""
    parser = argparse.ArgumentParser(
        prog='python -m inertia_ros',
        description='Estimate a rigid body\'s inertia tensor from gyro and torque streams.')
    sub = parser.add_subparsers(dest='command', metavar='COMMAND')
    for name in COMMANDS:
        importlib.import_module(f'inertia_ros.cli.{name}').add_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the command line; return the process exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if getattr(args, 'func', None) is None:
        parser.print_help(sys.stderr)
        return 2
    try:
        return int(args.func(args) or 0)
    except UserError as exc:
        print(f'inertia_ros {args.command}: error: {exc}', file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f'inertia_ros {args.command}: interrupted', file=sys.stderr)
        return 130
