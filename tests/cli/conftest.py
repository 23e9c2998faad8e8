"""Fixtures shared by the tests of ``dqcontrol.cli``: the README's first run, saved once."""

from __future__ import annotations

import pytest

from dqcontrol.cli import main


@pytest.fixture(scope="session")
def default_run(tmp_path_factory):
    """``dqcontrol run --short``: the README's first command, in CI's fast mode."""
    out = tmp_path_factory.mktemp("results")
    code = main(["run", "--short", "--out", str(out)])
    return code, out / "lbr4p_circle_T2s_mujoco"
