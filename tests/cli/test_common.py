"""The options every subcommand spells the same way (dqcontrol/cli/common.py): ``--out`` and
``--no-progress``, on their own and on every subcommand of ``dqcontrol``."""

from __future__ import annotations

import argparse

from dqcontrol.cli import build_parser
from dqcontrol.cli.common import NO_BARS_HELP, add_out_option, add_progress_option

_SUBCOMMANDS = ("run", "table1", "faults", "view", "bench", "sim-server")


def test_no_progress_sets_progress_false():
    parser = argparse.ArgumentParser()
    add_progress_option(parser, NO_BARS_HELP)
    assert parser.parse_args([]).progress is True
    assert parser.parse_args(["--no-progress"]).progress is False
    assert NO_BARS_HELP in parser.format_help()


def test_out_has_its_default_in_the_help():
    parser = argparse.ArgumentParser()
    add_out_option(parser, "results", "results folder")
    assert parser.parse_args([]).out == "results"
    assert parser.parse_args(["--out", "x"]).out == "x"
    assert "results folder (default: results)" in " ".join(parser.format_help().split())
    bare = argparse.ArgumentParser()
    add_out_option(bare, None, "folder of the files", metavar="FILE")
    assert bare.parse_args([]).out is None
    text = " ".join(bare.format_help().split())
    assert "--out FILE folder of the files" in text and "default" not in text


def test_every_subcommand_takes_no_progress():
    parser = build_parser()
    minimal = {"view": ["RUN.npz"]}
    for name in _SUBCOMMANDS:
        args = parser.parse_args([name, *minimal.get(name, []), "--no-progress"])
        assert args.progress is False, name
        args = parser.parse_args([name, *minimal.get(name, [])])
        assert args.progress is True, name


def test_every_subcommand_that_writes_takes_out():
    parser = build_parser()
    minimal = {"view": ["RUN.npz"]}
    for name in ("run", "table1", "faults", "view", "bench"):
        args = parser.parse_args([name, *minimal.get(name, []), "--out", "somewhere"])
        assert args.out == "somewhere", name
