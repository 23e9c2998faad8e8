"""The path-following controller in the fault campaign: it is one of the campaign's
controllers, and the cases where it once failed the campaign's judgement now pass it."""

from __future__ import annotations

import csv

from dqcontrol.cli import main
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


def test_the_cli_runs_it(tmp_path, capsys):
    code = main(
        ["faults", "--simulator", "kinematic", "--controllers", PF, "--faults",
         "nominal,qp_crossed", "--trajectories", "circle", "--out", str(tmp_path),
         "--workers", "1", "--no-progress"]
    )  # fmt: skip
    assert code == 0
    rows = list(csv.DictReader(open(tmp_path / "faults.csv", encoding="utf-8")))
    assert [(r["fault"], r["controller"], r["status"]) for r in rows] == [
        ("nominal", PF, "completed"),
        ("qp_crossed", PF, "completed"),
    ]
    assert "2/2 cases without violation" in capsys.readouterr().out


def test_noise_near_the_limits_stops_still():
    """A task stalled near the limits under measurement noise stands still (the noise-free
    case stops there too) instead of chasing the noise."""
    r = run_case(_case("near_limits_noise", "circle", "kinematic"))
    _judged(r)
    assert r.status in ("stopped", "completed"), r.row()


class _FirstTwoSeconds(CaseSpec):
    """A case cut at 2 s (the joint reaches its limit at 1.75 s)."""

    max_time_s = 2.0


def test_delay_near_the_limits_keeps_the_true_joints_inside_in_mujoco():
    """Near the limits with a 2-period delay (compensated) the servo's lag must not carry
    a joint past its limit: the sinusoid's first swing brings joint 6 to its lower limit at
    1.36 rad/s. The campaign tells the controller the MuJoCo servo it drives (τ_v), whose
    lag its prediction then counts."""
    base = _case("near_limits_delay_2", "sinusoid", "mujoco")
    spec = _FirstTwoSeconds(base.controller, base.trajectory, base.fault, "mujoco", 4.0)
    r = run_case(spec)
    assert r.raised == "" and not r.nan_seen, r.row()
    assert r.q_violations_true == 0, r.row()
