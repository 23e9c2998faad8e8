"""The ``dqcontrol`` command.

Each subcommand lives in a module ``dqcontrol/cli/<name>_cmd.py`` that defines
``register(subparsers)``: it adds its parser and sets ``func`` (a callable taking the parsed
arguments and returning an exit code). Errors of the library are printed as one line on
stderr with exit code 1; bad options exit with code 2 (argparse's convention).
"""

from __future__ import annotations

import argparse
import importlib
import pkgutil
import sys

from dqcontrol import __version__
from dqcontrol.errors import DQControlError, user_interrupt

__all__ = ["build_parser", "main"]


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every ``*_cmd`` module's subcommand registered."""
    parser = argparse.ArgumentParser(
        prog="dqcontrol",
        description="Kinematic control of redundant manipulators with dual quaternions.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    package = sys.modules[__name__]
    names = sorted(
        m.name for m in pkgutil.iter_modules(package.__path__) if m.name.endswith("_cmd")
    )
    for name in names:
        importlib.import_module(f"{__name__}.{name}").register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``dqcontrol`` console script."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except DQControlError as exc:
        print(f"dqcontrol {args.command}: error: {exc}", file=sys.stderr)
        return 1
    except (KeyboardInterrupt, SystemError) as exc:  # SystemError: through compiled code
        if not user_interrupt(exc):
            raise
        print(f"dqcontrol {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
