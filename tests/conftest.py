"""Shared fixtures of the test suite.

* ``tests/`` is put on ``sys.path`` so that test modules can ``import dh_reference`` (the
  independent DH oracle) without making ``tests`` a package.
* ``lbr4p`` and ``panda``: the two shipped robots, loaded once per session. Tests must not
  mutate them (they share Pinocchio workspaces, which every call overwrites anyway).
* Hypothesis profile ``ci`` (loaded by default): derandomised (seeded), no deadline (the
  first call of a Pinocchio function can be slow) and ~100 examples per property. Select
  another profile with ``pytest --hypothesis-profile=<name>``.
* Under pytest-xdist (``-n 2`` in pyproject's addopts) a wall-clock test runs alone
  (``wall_clock_lock.py``).
"""

from __future__ import annotations

import sys
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

import dqcontrol

_TESTS_DIR = str(Path(__file__).resolve().parent)
if _TESTS_DIR not in sys.path:
    sys.path.insert(0, _TESTS_DIR)

settings.register_profile(
    "ci",
    deadline=None,
    max_examples=100,
    derandomize=True,  # seeded: the same examples on every run and machine
    database=None,  # derandomised runs need no example database (no .hypothesis/ folder)
    suppress_health_check=[HealthCheck.too_slow],
)
settings.register_profile("thorough", deadline=None, max_examples=2000)
settings.load_profile("ci")

from wall_clock_lock import held, is_wall_clock, lock_folder  # noqa: E402 - tests/ on the path


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line(
        "markers", "wall_clock: keeps or measures wall time; runs alone under pytest-xdist"
    )


@pytest.hookimpl(wrapper=True)
def pytest_runtest_protocol(item: pytest.Item, nextitem: pytest.Item | None):
    folder = lock_folder(item.config)
    if folder is None:
        return (yield)
    with held(folder, exclusive=is_wall_clock(item)):
        return (yield)


@pytest.fixture(scope="session")
def lbr4p() -> dqcontrol.RobotModel:
    """The thesis's KUKA LBR4p (``robots/lbr4p/lbr4p.urdf``), end-effector ``lbr4p_flange``."""
    return dqcontrol.load_lbr4p()


@pytest.fixture(scope="session")
def panda() -> dqcontrol.RobotModel:
    """The Franka Panda of example-robot-data, fingers locked, end-effector ``panda_hand_tcp``."""
    return dqcontrol.load_panda()
