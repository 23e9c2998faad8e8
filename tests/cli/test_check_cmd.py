"""``dqcontrol check`` (dqcontrol/cli/check_cmd.py): its options, a missing run → exit code 2,
the limits a run is checked against (a named profile, or the URDF's limits of the robot
rebuilt from the run's meta), and whole checks of hand-made saved runs (exit codes 0/1/2,
the lines printed) and of a run that recorded its limit profile."""

from __future__ import annotations

import json

import numpy as np
import pytest
from runs.test_check import NAMES, _clean, _commands, _log

from dqcontrol.cli import build_parser, main
from dqcontrol.cli.check_cmd import _limits
from dqcontrol.errors import ParameterError
from dqcontrol.model.limit_profile import load_profile


def test_the_options():
    args = build_parser().parse_args(["check", "run.json"])
    assert (args.run, args.limits, args.period) == ("run.json", None, None)
    args = build_parser().parse_args(["check", "r", "--limits", "ur5e", "--period", "0.002"])
    assert (args.limits, args.period) == ("ur5e", 0.002)


def test_a_missing_run_exits_2_naming_it(tmp_path, capsys):
    assert main(["check", str(tmp_path / "none.json")]) == 2
    err = capsys.readouterr().err
    assert err == f"dqcontrol check: error: RUN: no saved run at {str(tmp_path / 'none.json')!r}\n"


def test_urdf_means_the_limits_of_the_runs_robot(lbr4p):
    name, limits = _limits("urdf", {"robot": "lbr4p", "limits": "franka_panda"})
    assert name == "urdf"
    np.testing.assert_array_equal(limits.qd_max, lbr4p.limits.qd_max)
    np.testing.assert_array_equal(limits.q_min, lbr4p.limits.q_min)


def test_the_profile_given_else_the_runs_own():
    name, profile = _limits("franka_panda", {"robot": "lbr4p"})
    assert name == "franka_panda" and profile.name == "franka_panda"
    np.testing.assert_array_equal(profile.qd_max, load_profile("franka_panda").qd_max)
    name, _ = _limits(None, {"limits": "ur5e"})
    assert name == "ur5e"


def test_urdf_limits_without_a_robot_suggest_a_profile():
    with pytest.raises(ParameterError) as info:
        _limits(None, {"joint_names": ["a", "b"]})  # no profile, no robot: the URDF's
    message = str(info.value)
    assert "no 'robot' in its meta" in message
    assert message.endswith("; without its robot, check against a profile: --limits NAME|FILE.toml")


# ---------------------------------------------------------------------- whole checks of saved runs
# the hand-made runs (_log, _clean: T = 0.01 s, joints NAMES) are tests/runs/test_check.py's
PROFILE_TOML = """source = "a test"
control_periods_s = [0.01]
[[joint]]
name = "a"
position_rad = [-1.0, 1.0]
velocity_rad_s = 1.0
acceleration_rad_s2 = 1.5
jerk_rad_s3 = 1000.0
[[joint]]
name = "b"
position_rad = [-1.0, 1.0]
velocity_rad_s = 1.0
acceleration_rad_s2 = 1.5
jerk_rad_s3 = 1000.0
"""


def _save(tmp_path, u: np.ndarray, meta: dict | None = None) -> str:
    log = _log(u)
    np.savez(tmp_path / "run.npz", **log.arrays())
    record = {"format": "dqcontrol-run", "version": 1, "npz": "run.npz", "meta": meta or log.meta}
    (tmp_path / "run.json").write_text(json.dumps(record), encoding="utf-8")
    (tmp_path / "test.toml").write_text(PROFILE_TOML, encoding="utf-8")
    return str(tmp_path / "run.json")


def test_the_cli_exit_codes_and_lines(tmp_path, capsys):
    path = _save(tmp_path, _clean())
    limits = str(tmp_path / "test.toml")
    assert main(["check", path, "--limits", limits]) == 0
    assert capsys.readouterr().out.startswith("check PASS run.json: 40 samples")
    u = _clean()
    u[:, 1] = _commands([1.0] * 9 + [2.0, 0.0] + [1.0] * 9 + [-1.0] * 20)
    path = _save(tmp_path, u)
    assert main(["check", path, "--limits", limits]) == 1
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("acceleration of b at sample 9 (t = 0.09 s): 2 > 1.5 rad/s²")
    assert lines[-1].startswith("check FAIL") and "acceleration 1" in lines[-1]


def test_the_cli_refuses_bad_input_with_exit_code_2(tmp_path, capsys):
    path = _save(tmp_path, _clean(), meta={"joint_names": list(NAMES)})  # no period
    limits = str(tmp_path / "test.toml")
    cases = [
        (["check", str(tmp_path / "none.json")], "no saved run"),
        (["check", path, "--limits", "nope", "--period", "0.01"], "franka_panda"),
        (["check", path, "--limits", "franka_panda", "--period", "0.01"], "panda_joint1"),
        (["check", path, "--limits", limits], "--period"),
        (["check", path, "--period", "0.01"], "--limits"),  # no robot to take the URDF of
    ]
    for argv, word in cases:
        assert main(argv) == 2, argv
        assert word in capsys.readouterr().err, argv
    assert main(["check", path, "--limits", limits, "--period", "0.01"]) == 0


def test_the_cli_defaults_to_the_runs_profile_and_urdf_means_the_urdfs_limits(tmp_path, capsys):
    from dqcontrol.model.library import PANDA_Q0

    panda = [f"panda_joint{k}" for k in range(1, 8)]
    u = np.zeros((3, 7))
    u[0] = 0.01  # from rest: 10 rad/s² and 10000 rad/s³, beyond Franka's jerk, no URDF limit
    log = _log(np.zeros((3, 2)))
    arrays = {**log.arrays(), "q": np.tile(PANDA_Q0, (3, 1)), "qd_command": u}
    arrays.update(qd_measured=np.zeros((3, 7)), torque=np.zeros((3, 7)))
    arrays.update(torque_peak=np.zeros((3, 7)))
    np.savez(tmp_path / "run.npz", **arrays)
    meta = {"robot": "panda", "limits": "franka_panda", "period_s": 0.001, "joint_names": panda}
    record = {"format": "dqcontrol-run", "version": 1, "npz": "run.npz", "meta": meta}
    (tmp_path / "run.json").write_text(json.dumps(record), encoding="utf-8")
    assert main(["check", str(tmp_path / "run.json")]) == 1
    assert "against 'franka_panda'" in capsys.readouterr().out
    assert main(["check", str(tmp_path / "run.json"), "--limits", "urdf"]) == 0
    assert "check PASS run.json: 3 samples at T = 0.001 s against 'urdf'" in capsys.readouterr().out


def test_a_run_records_its_profile_and_the_checker_reads_it(tmp_path, capsys):
    from dqcontrol.runs.storage import load_run

    argv = ["run", "--robot", "panda", "--limits", "franka_panda", "--simulator", "kinematic"]
    argv += ["--period", "0.001", "--duration", "0.3", "--controllers", "local", "--short"]
    assert main([*argv, "--no-viewer", "--out", str(tmp_path)]) == 0
    (saved,) = tmp_path.glob("**/local.json")
    log, _ = load_run(saved)
    profile = load_profile("franka_panda")
    assert log.meta["limits"] == "franka_panda"
    np.testing.assert_array_equal(log.meta["velocity_limits"], profile.qd_max)
    acc = np.abs(np.diff(np.vstack((np.zeros(7), log.qd_command)), axis=0)) / 0.001
    assert np.all(acc <= profile.qdd_max * (1 + 1e-9))  # the profile's acceleration flowed in
    capsys.readouterr()
    code = main(["check", str(saved)])
    out = capsys.readouterr().out
    # the profile's jerk flowed in too, and the run ends with the stop along the path
    assert code == 0 and "check PASS" in out and "against 'franka_panda'" in out, out
    assert log.stopping.any() and not log.qd_command[-1].any()
