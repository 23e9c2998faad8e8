"""The fast paths of the control step equal the straightforward computations they replace:
batched kinematics, the fused target pair, the stacked bound computation, the
Cholesky solve of the proportional controller, the default QP backend rule, and the
benchmark's JSON (its figures are timings: never asserted here)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from dqcontrol.cli.bench_cmd import load_bench
from dqcontrol.controllers import LocalController
from dqcontrol.controllers.core.bounds import (
    braking_speed,
    command_box,
    intersect_acceleration,
    velocity_position_box,
)
from dqcontrol.controllers.proportional import _solve_spd
from dqcontrol.controllers.thesis.controller import DEFAULT_SOLVER
from dqcontrol.errors import ParameterError
from dqcontrol.model import RobotModel
from dqcontrol.trajectories import Circle, FunctionTrajectory, Sinusoid, WaypointTrajectory

#: the synthetic serial chains of the benchmark (benchmarks/bench.py)
long_chain_urdf = load_bench().long_chain_urdf


@pytest.fixture(scope="module")
def chain14() -> RobotModel:
    return RobotModel.from_urdf(long_chain_urdf(14), "flange")


@pytest.mark.parametrize("robot_name", ["lbr4p", "chain14"])
def test_batched_kinematics_equal_single_calls(robot_name, request):
    robot = request.getfixturevalue(robot_name)
    qs = robot.random_configurations(50, seed=3)
    xs, jacs = robot.poses_and_jacobians(qs)
    for q, x, jac in zip(qs, xs, jacs, strict=True):
        x1, jac1 = robot.pose_and_jacobian(q)
        np.testing.assert_allclose(x, x1, rtol=0, atol=1e-12)
        np.testing.assert_allclose(jac, jac1, rtol=0, atol=1e-12)
        assert x[0] >= 0.0  # r_w ≥ 0, as the single path


def _trajectories():
    ref = np.array([1.0, 0, 0, 0, 0, 0.05, -0.1, 0.2])
    yield Circle(2.0, reference=ref)
    yield Sinusoid(4.0, reference=ref)
    yield WaypointTrajectory(
        np.array([[0, 0, 0], [0.1, 0, 0], [0.1, 0.1, 0.05]]), duration_s=3.0, reference=ref
    )
    circle = Circle(2.0)
    yield FunctionTrajectory(circle.local_pose, None, 2.0, reference=ref)


@pytest.mark.parametrize("traj", list(_trajectories()), ids=lambda t: type(t).__name__)
def test_target_pair_equals_target_and_derivative(traj):
    duration = traj.duration
    for sigma in (-0.3, 0.0, 0.1234, 0.5 * duration, duration - 1e-9, duration, duration + 1):
        pair = traj.target_pair(sigma)
        np.testing.assert_allclose(pair[0], traj.target(sigma), rtol=0, atol=1e-15)
        np.testing.assert_allclose(pair[1], traj.target_derivative(sigma), rtol=0, atol=1e-15)


def _reference_box(q, q_min, q_max, qd_max, period_s, a_max):
    """The bounds as first written (one side at a time), the oracle of the stacked pass."""
    lo = np.maximum(-qd_max, (q_min - q) / period_s)
    hi = np.minimum(qd_max, (q_max - q) / period_s)
    if a_max is not None:
        hi = np.minimum(hi, braking_speed(q_max - q, a_max, period_s))
        lo = np.maximum(lo, -braking_speed(q - q_min, a_max, period_s))
    hi = np.maximum(hi, np.minimum(lo, qd_max))
    lo = np.minimum(lo, hi)
    return lo, hi


@pytest.mark.parametrize("braking", [True, False])
@pytest.mark.parametrize("shape", [(7,), (10, 7)])
def test_stacked_bounds_equal_the_reference(braking, shape):
    rng = np.random.default_rng(7)
    q_min, q_max = -np.full(7, 2.9), np.full(7, 2.9)
    qd_max = rng.uniform(1.0, 3.0, 7)
    for _ in range(50):
        q = rng.uniform(-3.2, 3.2, shape)  # some beyond the limits
        a = rng.uniform(0.5, 40.0, shape) if braking else None
        for period in (0.001, 0.05):
            got = velocity_position_box(q, q_min, q_max, qd_max, period, a)
            want = _reference_box(q, q_min, q_max, qd_max, period, a)
            np.testing.assert_array_equal(got[0], want[0])
            np.testing.assert_array_equal(got[1], want[1])
    q = rng.uniform(-3.0, 3.0, 7)
    box = command_box(q, np.zeros(7), q_min, q_max, qd_max, np.full(7, 10.0), 0.001)
    lo, hi = _reference_box(q, q_min, q_max, qd_max, 0.001, np.full(7, 10.0))
    want = intersect_acceleration(lo, hi, np.zeros(7), np.full(7, 0.01))
    np.testing.assert_array_equal(box.lower, want.lower)
    np.testing.assert_array_equal(box.upper, want.upper)


def test_cholesky_solve_equals_lu_and_falls_back():
    rng = np.random.default_rng(1)
    n_mat = rng.normal(size=(8, 7))
    gram = n_mat @ n_mat.T + 1e-6 * np.eye(8)
    rhs = rng.normal(size=8)
    np.testing.assert_allclose(_solve_spd(gram, rhs), np.linalg.solve(gram, rhs), rtol=1e-9)
    indefinite = np.diag([1.0, -1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0])
    np.testing.assert_allclose(_solve_spd(indefinite, rhs), np.linalg.solve(indefinite, rhs))


def test_default_solver_rule(lbr4p):
    assert DEFAULT_SOLVER == "daqp"
    # settings never pick the backend: OSQP's given to the default are refused
    traj = Circle(2.0)
    with pytest.raises(ParameterError, match="DAQP has no setting.*max_iter"):
        LocalController(lbr4p, traj, period_s=0.05, solver_settings={"max_iter": 1})
    ctrl = LocalController(
        lbr4p, traj, period_s=0.05, solver="osqp", solver_settings={"max_iter": 1}
    )
    assert type(ctrl.backend).__name__ == "OsqpBackend"


def test_quick_bench_writes_every_figure(tmp_path):
    bench = load_bench()
    TARGETS, main = bench.TARGETS, bench.main

    out = tmp_path / "bench.json"
    res = main(out=out, quick=True)
    data = json.loads(out.read_text())
    assert data["quick"] is True and data["default_solver"] == "daqp"
    assert set(data["targets"]) == set(TARGETS)
    for key in ("cpu", "cores", "python", "packages"):
        assert key in data["machine"]
    for name in ("local[daqp]", "predictive_p6[daqp]", "predictive_p10[daqp]", "proportional"):
        assert data["controllers"][name]["median_us"] > 0.0
        # the host's floor: a constant workload timed after every step
        assert data["controllers"][name]["reference_p99_over_median"] >= 1.0
        # present only if the repeated closed loops ended in the same state bit for bit
        assert data["controllers"][name]["own_p99_over_median"] >= 1.0
    assert data["controllers"]["predictive_noscale_p10[daqp]"]["median_us"] > 0.0
    assert data["targets"]["p99_over_median"]["host_floor"] >= 1.0
    assert data["targets"]["p99_over_median"]["own_work"] >= 1.0
    assert data["mujoco"]["realtime_factor"] > 0.0
    pf10 = data["path_following"]["by_p"]["10"]
    # the prioritised solve holds the solver calls: never shorter than them
    assert 0.0 < pf10["solver_median_us"] <= pf10["levels_median_us"] <= pf10["median_us"]
    for key in ("path_following_p10", "path_following_step_over_solve"):
        assert data["targets"][key]["value"] > 0.0
    default = data["path_following"]["dynamics_p10"]  # the dynamics-aware bound, as shipped
    assert 0.0 < default["solver_median_us"] <= default["levels_median_us"] <= default["median_us"]
    assert data["scaling"]["by_p"] and data["scaling"]["by_joints_p10"]
    whole = data["collision"]["pf10_whole_circle"]  # the quick run: its first 20 steps
    assert whole["steps"] == 20 and not whole["completed"] and whole["fallbacks"] == 0
    assert whole["step_median_us"] <= whole["step_p99_us"] and 0.0 <= whole["over_period_share"]
    assert whole["closest_mm"] is None or whole["closest_mm"] > 20.0  # still far from the ball
    for v in data["agreement"].values():
        assert v["max_abs_qd_diff"] < 1e-8  # accuracy, not time: the backends agree
    assert res["targets"].keys() == data["targets"].keys()
    if data["dqrobotics"] is not None:  # a dev extra: the peers are measured interleaved
        assert data["dqrobotics"]["rounds"] >= 3
        assert set(data["ratios"]) == {
            "single_kinematics_vs_dqr",
            "batch10_vs_10x_dqr",
            "local_step_vs_dqr_classic_qp",
        }
        assert all(v > 0.0 for v in data["ratios"].values())


def test_compiled_cost_equals_numpy_blocks():
    """``qp_cost.add_task_grams`` (after ``align_signs``) against the plain numpy cost of
    docs/theory.md §4 for p instants (flips where ``x_i · x_d,i < 0``, stall damping on the qd
    diagonal), and ``scatter_symmetric`` against fancy indexing."""
    from dqcontrol.controllers.core.task_kernels import (
        add_task_grams,
        align_signs,
        scatter_symmetric,
    )

    rng = np.random.default_rng(5)
    p, n = 10, 7
    m = n + 1
    xs = rng.standard_normal((p, 8))
    jacs = rng.standard_normal((p, 8, n))
    xd = rng.standard_normal((p, 8))
    dxd = rng.standard_normal((p, 8))
    gain, weight, stall = 10.0, 2.5, 1e-3
    diag = np.zeros((p, m, m))
    diag[:, np.arange(n), np.arange(n)] = 1e-4
    diag[:, n, n] = 1e-2
    rows, cols = np.triu_indices(m)
    sign = np.where((xs * xd).sum(axis=1) < 0.0, -1.0, 1.0)
    assert (sign < 0).any() and (sign > 0).any()
    g = np.concatenate(
        (jacs * sign[:, None, None], (gain * (xs * sign[:, None] - xd) - dxd)[:, :, None]), axis=2
    )
    blocks = weight * np.matmul(g.transpose(0, 2, 1), g) + diag
    blocks[:, np.arange(n), np.arange(n)] += stall
    expected = 2.0 * blocks
    xs_in, jacs_in = xs.copy(), jacs.copy()
    align_signs(xs_in, jacs_in, xd)
    got = 2.0 * diag
    add_task_grams(xs_in, jacs_in, xd, dxd, gain, 2.0 * weight, got)
    got[:, np.arange(n), np.arange(n)] += 2.0 * stall
    np.testing.assert_allclose(got, expected, rtol=1e-13, atol=1e-13)
    np.testing.assert_array_equal(got, got.transpose(0, 2, 1))  # exactly symmetric
    np.testing.assert_array_equal(xs_in, xs * sign[:, None])  # flipped in place
    np.testing.assert_array_equal(jacs_in, jacs * sign[:, None, None])

    values = got[0][rows, cols]
    h = np.zeros((m, m))
    scatter_symmetric(h, rows.astype(np.int64), cols.astype(np.int64), values)
    ref = np.zeros((m, m))
    ref[rows, cols] = values
    ref[cols, rows] = values
    np.testing.assert_array_equal(h, ref)


@pytest.mark.parametrize("braking", [True, False])
def test_vp_boxes_equal_numpy_vp_box_bit_for_bit(braking):
    """The joint-box kernels (``joint_box.applied_box_into`` on ``q`` for instant 0,
    ``predicted_boxes_into`` on the clipped predictions for the others) against
    ``bounds._vp_box``: random states with joints beyond their limits, per-instant braking
    constants."""
    from dqcontrol.controllers.core.bounds import _vp_box, braking_constants
    from dqcontrol.controllers.core.box_rules import applied_box_into, predicted_boxes_into

    rng = np.random.default_rng(17 + braking)
    beyond = 0
    for _ in range(300):
        p, n = int(rng.integers(1, 12)), int(rng.integers(1, 9))
        q_min = rng.uniform(-3.0, -0.5, n)
        q_max = rng.uniform(0.5, 3.0, n)
        span = q_max - q_min
        q = q_min + rng.uniform(-0.02, 1.02, n) * span  # sometimes beyond a limit
        q_hat = q_min + rng.uniform(-0.1, 1.1, (p, n)) * span
        q_hat[0] = q
        qd_max = rng.uniform(0.5, 8.0, n)
        period = float(rng.choice([1e-3, 0.01, 0.05]))
        a_max = rng.uniform(0.5, 50.0, (p, n))
        brake = braking_constants(a_max, period)
        q_box = np.minimum(np.maximum(q_hat, q_min), q_max)
        q_box[0] = q
        lo_ref, hi_ref = _vp_box(q_box, q_min, q_max, qd_max, period, brake if braking else None)
        lower, upper = np.full(p * n, -np.inf), np.full(p * n, np.inf)
        index = np.arange(p * n).reshape(p, n)
        stacked = np.array(brake)
        applied_box_into(
            q, q_min, q_max, qd_max, period, braking, stacked[:, 0], index[0], lower, upper
        )
        predicted_boxes_into(
            q_hat, q_min, q_max, qd_max, period, braking, stacked, index, lower, upper
        )
        np.testing.assert_array_equal(lower.reshape(p, n), lo_ref)
        np.testing.assert_array_equal(upper.reshape(p, n), hi_ref)
        beyond += bool(np.any((q < q_min) | (q > q_max)))
    assert beyond > 20  # the beyond-a-limit rule was exercised


def test_predictive_daqp_takes_the_least_distance_form(lbr4p):
    """The predictive controllers' DAQP solves go through ``qp_ldp.py`` (their blocks are
    positive definite with the default μ and λ2): the plain workspace is never set up."""
    from dqcontrol.controllers import PredictiveController, PredictiveNoScalingController
    from dqcontrol.model import LBR4P_Q0

    robot = lbr4p
    for cls in (PredictiveController, PredictiveNoScalingController):
        ctrl = cls(robot, Circle(2.0), 1e-3, num_instants=6, acceleration_limit=10.0)
        q = np.array(LBR4P_Q0)
        ctrl.reset(q)
        for _ in range(200):
            res = ctrl.step(q)
            assert res.diagnostics.status == "solved"
            q = q + 1e-3 * res.qd_command
        assert ctrl.backend._blocks._block == robot.nq + 1
        assert ctrl.backend._blocks._ldp_model is not None and ctrl.backend._blocks._model is None


def test_compiled_kernels_work_without_a_writable_cache(monkeypatch):
    """Where Numba finds no writable cache location it refuses ``cache=True`` at decoration;
    ``dqcontrol._compiled.compiled`` then compiles in memory instead of failing the import."""
    import numba

    import dqcontrol._compiled as comp

    real = numba.njit

    def refusing_njit(*args, **kwargs):
        if kwargs.get("cache"):
            raise RuntimeError("cannot cache function 'f': no locator available for file 'x'")
        return real(*args, **kwargs)

    monkeypatch.setattr(comp, "njit", refusing_njit)

    def twice(x):
        return 2.0 * x

    kernel = comp.compiled(twice)
    assert kernel(1.5) == 3.0 and hasattr(kernel, "signatures")
