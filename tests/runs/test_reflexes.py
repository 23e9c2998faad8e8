"""dqcontrol/runs/reflexes.py: the command monitor against finite differences of seeded random
command streams computed with numpy, its tolerance, its position and at-rest checks, and
the one-line description of a violation."""

from __future__ import annotations

import numpy as np
import pytest

from dqcontrol.runs.reflexes import KINDS, RELATIVE_TOLERANCE, CommandMonitor, Violation

T = 0.01
NAMES = ("a", "b", "c")
QD_MAX = np.array([1.0, 2.0, np.inf])
QDD_MAX = np.array([20.0, 30.0, 40.0])
QDDD_MAX = np.array([1500.0, np.inf, 3000.0])


def _monitor() -> CommandMonitor:
    return CommandMonitor(NAMES, T, QD_MAX, qdd_max=QDD_MAX, qddd_max=QDDD_MAX)


@pytest.mark.parametrize("seed", range(3))
def test_the_violations_are_those_of_the_finite_differences(seed):
    rng = np.random.default_rng(seed)
    u = rng.uniform(-1.5, 1.5, (30, 3)) * np.array([1.0, 2.0, 5.0])
    padded = np.vstack((np.zeros((2, 3)), u))  # the arm starts at rest
    acc = np.diff(padded, axis=0)[1:] / T
    jerk = np.diff(padded, n=2, axis=0) / T**2
    expected = set()
    for kind, values, limits in (("velocity", u, QD_MAX), ("acceleration", acc, QDD_MAX),
                                 ("jerk", jerk, QDDD_MAX)):  # fmt: skip
        for k, j in zip(*np.nonzero(np.abs(values) > limits), strict=True):
            expected.add((kind, int(k), NAMES[j], float(values[k, j])))
    monitor = _monitor()
    found = [v for k, uk in enumerate(u) for v in monitor.command(k, k * T, uk)]
    assert expected  # the draw has violations of each kind to find
    assert {v.kind for v in found} == {"velocity", "acceleration", "jerk"}
    assert {(v.kind, v.sample, v.joint) for v in found} == {e[:3] for e in expected}
    for v in found:
        value = next(e[3] for e in expected if e[:3] == (v.kind, v.sample, v.joint))
        assert v.value == pytest.approx(value, rel=1e-12)
        assert abs(v.limit) in (QD_MAX[NAMES.index(v.joint)], QDD_MAX[NAMES.index(v.joint)],
                                QDDD_MAX[NAMES.index(v.joint)])  # fmt: skip
        assert np.sign(v.limit) == np.sign(v.value) and v.t_s == v.sample * T


def test_a_value_within_the_relative_tolerance_is_within():
    monitor = CommandMonitor(NAMES, T, np.ones(3))
    assert monitor.command(0, 0.0, np.full(3, 1.0 + 0.5 * RELATIVE_TOLERANCE)) == []
    (found,) = monitor.command(1, T, np.array([1.0 + 3 * RELATIVE_TOLERANCE, 0.0, 0.0]))
    assert found.kind == "velocity" and found.joint == "a"


def test_a_reset_starts_again_from_rest():
    monitor = _monitor()
    step = np.array([0.1, 0.0, 0.0])  # 10 rad/s² and 1000 rad/s³ from rest
    assert monitor.command(0, 0.0, step) == []
    assert monitor.command(1, T, step) == []  # no change: no acceleration
    monitor.reset()
    assert monitor.command(0, 0.0, step) == []  # from rest again, not a step back to 0
    assert monitor.u_1.tolist() == step.tolist() and not monitor.u_2.any()


def test_positions_outside_their_limits():
    monitor = CommandMonitor(NAMES, T, QD_MAX, q_min=[-1.0, -1.0, -1.0], q_max=[1.0, 2.0, 3.0])
    found = monitor.position(4, 0.04, np.array([1.5, -1.2, 3.0]))
    assert [(v.joint, v.value, v.limit) for v in found] == [("a", 1.5, 1.0), ("b", -1.2, -1.0)]
    assert all(v.kind == "position" and v.sample == 4 for v in found)
    assert CommandMonitor(NAMES, T, QD_MAX).position(0, 0.0, np.full(3, 1e9)) == []


def test_a_stream_that_does_not_end_at_rest():
    monitor = _monitor()
    monitor.command(0, 0.0, np.array([0.0, 0.05, 0.0]))
    (found,) = monitor.at_rest(0, 0.0)
    assert (found.kind, found.joint, found.value, found.limit) == ("not_at_rest", "b", 0.05, 0.0)
    monitor.command(1, T, np.array([0.0, 1e-10, 0.0]))  # below 1e-9 of 2 rad/s
    assert monitor.at_rest(1, T) == []


def test_a_violation_describes_itself_with_its_unit():
    jerk = Violation("jerk", 3, 0.03, "b", -4000.0, -3750.0)
    assert jerk.unit == "rad/s³"
    assert jerk.describe() == "jerk of b at sample 3 (t = 0.03 s): -4000 < -3750 rad/s³"
    rest = Violation("not_at_rest", 9, 0.09, "a", 0.5, 0.0)
    assert (
        rest.describe()
        == "not_at_rest of a at sample 9 (t = 0.09 s): last command 0.5 rad/s, not 0"
    )
    assert {Violation(k, 0, 0.0, "a", 1.0, 0.5).unit for k in KINDS} == {
        "rad", "rad/s", "rad/s²", "rad/s³",
    }  # fmt: skip
