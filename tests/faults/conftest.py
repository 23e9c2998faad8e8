"""Shared fixtures of the fault tests: the reduced campaign of CI, run once per session (the
campaign's and the report's tests read it)."""

from __future__ import annotations

import pytest

from dqcontrol.faults import run_campaign


@pytest.fixture(scope="session")
def quick_campaign():
    """The reduced campaign of CI: kinematic loop, 4 controllers, the circle, 11 faults."""
    return run_campaign(simulator="kinematic", quick=True)
