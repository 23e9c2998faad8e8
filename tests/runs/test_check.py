"""The checker (dqcontrol/runs/check.py): hand-made logs with one violation of each kind (found
at the right sample and joint), a clean log, a numpy reference on random commands, refused
profiles and the summary line."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from dqcontrol.model.limit_profile import LimitProfile, ProfileError
from dqcontrol.runs import RunLog, Violation, check_run
from dqcontrol.runs.check import summary_line

T = 0.01
NAMES = ("a", "b")


def _profile(**per_joint_a) -> LimitProfile:
    """Both joints: q in [-1, 1] rad, 1 rad/s, 1.5 rad/s², 1000 rad/s³; ``per_joint_a``
    changes joint a's entry."""
    arrays = {
        "q_min": np.array([-1.0, -1.0]),
        "q_max": np.array([1.0, 1.0]),
        "qd_max": np.array([1.0, 1.0]),
        "qdd_max": np.array([1.5, 1.5]),
        "qddd_max": np.array([1000.0, 1000.0]),
    }
    for name, value in per_joint_a.items():
        arrays[name][0] = value
    return LimitProfile("test", "a test", NAMES, **arrays, periods_s=(T,))


def _commands(accelerations: list[float]) -> np.ndarray:
    """The commands ``u_k = u_{k-1} + a_k T`` from rest [rad/s]."""
    return np.cumsum(np.array(accelerations) * T)


def _log(u: np.ndarray) -> RunLog:
    """A run of the commands ``u`` (K, 2), its positions integrated from 0."""
    k = u.shape[0]
    q = np.vstack((np.zeros((1, 2)), np.cumsum(u * T, axis=0)[:-1]))
    zeros = np.zeros((k, 2))
    arrays = {
        "t_s": T * np.arange(k), "sigma": T * np.arange(k), "s": np.ones(k), "q": q,
        "qd_measured": zeros, "qd_command": u, "torque": zeros, "torque_peak": zeros,
        "pose": np.zeros((k, 8)), "target": np.zeros((k, 8)),
        "solver_status": np.array(["solved"] * k), "iterations": np.zeros(k, dtype=int),
        "solve_time_s": np.zeros(k), "step_time_s": np.zeros(k),
        "fallback": np.zeros(k, bool), "relaxed": np.zeros(k, bool),
        "saturated": np.zeros(k, bool),
    }  # fmt: skip
    return RunLog.from_arrays(arrays, {"period_s": T, "joint_names": list(NAMES)})


#: Joint a: a triangle from rest to rest (1 rad/s² up for 20 samples, down for 20: the last
#: command is 0, the peak 0.2 rad/s at sample 19, the jerk -200 rad/s³ at sample 20); b: 0.
TRIANGLE = _commands([1.0] * 20 + [-1.0] * 20)


def _clean() -> np.ndarray:
    return np.column_stack((TRIANGLE, np.zeros(TRIANGLE.size)))


def test_a_clean_log_has_no_violation():
    assert TRIANGLE[-1] == pytest.approx(0.0, abs=1e-15)
    u = _clean()
    u[-1] = 0.0
    assert check_run(_log(u), _profile()) == []


def _one(log: RunLog, profile: LimitProfile) -> Violation:
    found = check_run(log, profile)
    assert len(found) == 1, found
    return found[0]


def test_one_position_violation():
    log = _log(_clean())
    log.q[15, 1] = 1.5
    v = _one(log, _profile())
    assert (v.kind, v.sample, v.joint, v.value, v.limit) == ("position", 15, "b", 1.5, 1.0)
    assert v.t_s == pytest.approx(0.15)


def test_one_velocity_violation():
    v = _one(_log(_clean()), _profile(qd_max=0.195))
    assert (v.kind, v.sample, v.joint, v.limit) == ("velocity", 19, "a", 0.195)
    assert v.value == pytest.approx(0.2)


def test_one_acceleration_violation():
    u = _clean()
    u[:, 1] = _commands([1.0] * 9 + [2.0, 0.0] + [1.0] * 9 + [-1.0] * 20)
    v = _one(_log(u), _profile())
    assert (v.kind, v.sample, v.joint, v.limit) == ("acceleration", 9, "b", 1.5)
    assert v.value == pytest.approx(2.0)


def test_one_jerk_violation():
    v = _one(_log(_clean()), _profile(qddd_max=150.0))
    assert (v.kind, v.sample, v.joint, v.limit) == ("jerk", 20, "a", -150.0)
    assert v.value == pytest.approx(-200.0)


def test_one_end_not_at_rest():
    v = _one(_log(_clean()[:-1]), _profile())
    assert (v.kind, v.sample, v.joint, v.limit) == ("not_at_rest", 38, "a", 0.0)
    assert v.value == pytest.approx(0.01)


def test_the_first_command_is_a_step_from_rest():
    u = np.zeros((3, 2))
    u[0, 1] = 0.12  # from rest: 12 rad/s², 1200 rad/s³; then back to 0 at once
    found = check_run(_log(u), _profile())
    assert [(v.kind, v.sample) for v in found] == [
        ("acceleration", 0), ("jerk", 0), ("acceleration", 1), ("jerk", 1), ("jerk", 2)
    ]  # fmt: skip
    assert [v.value for v in found] == pytest.approx([12.0, 1200.0, -12.0, -2400.0, 1200.0])


def test_the_tolerance_is_relative_1e_9():
    u = _clean()
    u[19, 0] = 0.2
    assert check_run(_log(u), _profile(qd_max=0.2 * (1 - 0.5e-9))) == []
    assert [v.kind for v in check_run(_log(u), _profile(qd_max=0.2 * (1 - 2e-9)))] == ["velocity"]


def test_random_commands_against_a_numpy_reference():
    rng = np.random.default_rng(7)
    u = rng.normal(0.0, 0.4, size=(200, 2))
    log = _log(u)
    log.q[:] = rng.uniform(-1.2, 1.2, size=log.q.shape)
    big = {"qdd_max": np.array([60.0, 60.0]), "qddd_max": np.array([8000.0, 8000.0])}
    profile = dataclasses.replace(_profile(), **big)
    padded = np.vstack((np.zeros((2, 2)), u))
    acc = np.diff(padded, axis=0)[1:] / T
    jerk = np.diff(padded, 2, axis=0) / T**2
    expected = {
        "position": np.argwhere(np.abs(log.q) > 1.0),
        "velocity": np.argwhere(np.abs(u) > 1.0),
        "acceleration": np.argwhere(np.abs(acc) > 60.0),
        "jerk": np.argwhere(np.abs(jerk) > 8000.0),
    }
    found = check_run(log, profile)
    for kind, where in expected.items():
        got = sorted((v.sample, NAMES.index(v.joint)) for v in found if v.kind == kind)
        assert got == sorted(map(tuple, where.tolist())), kind
        assert len(got) > 0, kind  # the draw exercises every kind
    samples = [v.sample for v in found if v.kind != "not_at_rest"]
    assert samples == sorted(samples) and found[-1].kind == "not_at_rest"


def test_a_profile_for_other_joints_and_the_urdf_profile_are_refused():
    other = dataclasses.replace(_profile(), joint_names=("x", "y"))
    with pytest.raises(ProfileError, match=r"\['x', 'y'\].*\['a', 'b'\]"):
        check_run(_log(_clean()), other)
    urdf = dataclasses.replace(_profile(), joint_names=())
    with pytest.raises(ProfileError, match="robot.limits"):
        check_run(_log(_clean()), urdf)


def test_the_summary_line():
    found = check_run(_log(_clean()), _profile(qddd_max=150.0))
    line = summary_line(found, 40, T, "test", "run.json")
    assert line.startswith("check FAIL run.json: 40 samples at T = 0.01 s against 'test'")
    assert "jerk 1" in line and "the reflex that would have fired: jerk of a at sample 20" in line
    assert summary_line([], 40, T, "test", "run.json").startswith("check PASS run.json")
