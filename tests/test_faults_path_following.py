"""The path-following controller in the fault campaign: it is one of the campaign's
controllers, and the cases where it once failed the campaign's judgement now pass it."""

from __future__ import annotations

from dqcontrol.faults.campaign import CaseSpec, run_case
from dqcontrol.faults.scenarios import (
    CONTROLLERS,
    QUICK_CONTROLLERS,
    TRAJECTORIES,
    fault_by_name,
)
from dqcontrol.registry import controller_spec
from dqcontrol.studies import load_study

PF = "path_following"


def _case(fault: str, traj: str, simulator: str) -> CaseSpec:
    """The campaign's case (the controller from the registry, as the campaign takes it)."""
    return CaseSpec(
        controller_spec("pf").renamed(PF), TRAJECTORIES[traj], fault_by_name(fault), simulator,
        TRAJECTORIES[traj].duration_s,
    )  # fmt: skip


def _judged(r) -> None:
    """The campaign's judgement of a QP controller's row."""
    assert r.safe and r.raised == "" and not r.nan_seen, r.row()
    assert r.status in ("completed", "stopped", "advancing"), r.row()


def test_path_following_is_a_campaign_controller():
    assert CONTROLLERS[PF].qp and CONTROLLERS[PF].num_instants == 10
    assert PF in QUICK_CONTROLLERS
    assert PF in load_study("faults").controllers


def test_noise_near_the_limits_stops_still():
    """A task stalled near the limits under measurement noise stands still (the noise-free
    case stops there too) instead of chasing the noise."""
    r = run_case(_case("near_limits_noise", "circle", "kinematic"))
    _judged(r)
    assert r.status in ("stopped", "completed"), r.row()
