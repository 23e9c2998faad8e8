"""Options every subcommand spells the same way."""

from __future__ import annotations

import argparse

__all__ = ["NO_BARS_HELP", "add_out_option", "add_progress_option"]


#: Help of ``--no-progress`` for a subcommand that draws no progress bar.
NO_BARS_HELP = "accepted as everywhere; this command draws no progress bar"


def add_progress_option(
    parser: argparse.ArgumentParser | argparse._ArgumentGroup,
    help_text: str = "no progress bars (by default they are shown on a terminal)",
) -> None:
    """``--no-progress``: no progress bars (``args.progress`` is ``False``)."""
    parser.add_argument("--no-progress", dest="progress", action="store_false", help=help_text)


def add_out_option(
    parser: argparse.ArgumentParser | argparse._ArgumentGroup,
    default: str | None,
    what: str,
    metavar: str = "DIR",
) -> None:
    """``--out``: where a subcommand writes; ``what`` completes the help text."""
    shown = f" (default: {default})" if default is not None else ""
    parser.add_argument("--out", default=default, metavar=metavar, help=f"{what}{shown}")
