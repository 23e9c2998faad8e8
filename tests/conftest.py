"""Shared fixtures of the test suite.

* ``tests/`` is put on ``sys.path`` so that test modules can ``import dh_reference`` (the
  independent DH oracle) without making ``tests`` a package.
* ``lbr4p`` and ``panda``: the two shipped robots, loaded once per session. Tests must not
  mutate them (they share Pinocchio workspaces, which every call overwrites anyway).
* Hypothesis profile ``ci`` (loaded by default): derandomised (seeded), no deadline (the
  first call of a Pinocchio function can be slow) and ~100 examples per property. Select
  another profile with ``pytest --hypothesis-profile=<name>``.
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


@pytest.fixture(scope="session")
def lbr4p() -> dqcontrol.RobotModel:
    """The thesis's KUKA LBR4p (``robots/lbr4p/lbr4p.urdf``), end-effector ``lbr4p_flange``."""
    return dqcontrol.load_lbr4p()


@pytest.fixture(scope="session")
def panda() -> dqcontrol.RobotModel:
    """The Franka Panda of example-robot-data, fingers locked, end-effector ``panda_hand_tcp``."""
    return dqcontrol.load_panda()
