"""The proportional controller (dqcontrol/controllers/proportional.py): its fused step
against the plain computation of docs/theory.md §4.1 and §5 — the box joint by joint
against ``command_box`` (bit for bit), the whole step against a straightforward reference on
seeded random states and over closed loops (to 1e-12), its Cholesky solve against LU (and
its fall-back on an indefinite matrix) — and its closed-loop behaviour:
exponential convergence at the rate ``K``, tracking, no bound crossed."""

from __future__ import annotations

import math

import numpy as np
import pytest
from controllers.thesis.test_controller import assert_tracked_and_turned, turning_waypoints

from dqcontrol.cli.bench_cmd import load_bench
from dqcontrol.controllers import ProportionalController, command_box
from dqcontrol.controllers import proportional as prop
from dqcontrol.controllers.base import StepDiagnostics, StepResult
from dqcontrol.controllers.core.bounds import braking_constants
from dqcontrol.controllers.core.box_rules import joint_boxes, joint_constants
from dqcontrol.dq import (
    dq_conj,
    dq_from_rt,
    dq_mul,
    qfrom_axis_angle,
)
from dqcontrol.dq.algebra import C8, haminus8
from dqcontrol.model import LBR4P_Q0, RobotModel
from dqcontrol.sim import run_kinematic
from dqcontrol.trajectories import Circle, FunctionTrajectory, Sinusoid

#: the synthetic serial chains of the benchmark (benchmarks/bench.py)
long_chain_urdf = load_bench().long_chain_urdf

THESIS_VEL = np.pi * np.array([1, 1, 1, 1, 2.5, 2.5, 2.5])
ONE = np.array([1.0, 0, 0, 0, 0, 0, 0, 0])


def reference_step(ctrl: ProportionalController, q: np.ndarray):
    """The proportional step written plainly (as before the fused version): the command,
    ``saturated``, the conflict joints, the message, the pose and the target."""
    x, jac = ctrl.robot.pose_and_jacobian(q)
    xd, dxd = ctrl.trajectory.target_pair(ctrl.sigma)  # as the step before (s = 1)
    if x @ xd < 0.0:
        x, jac = -x, -jac
    err = ONE - dq_mul(dq_conj(x), xd)
    n_mat = haminus8(xd) @ C8 @ jac
    rhs = ctrl.gain_per_s * err - dq_mul(dq_conj(x), dxd)
    gram = n_mat @ n_mat.T + ctrl.damping**2 * np.eye(8)
    y = np.linalg.solve(gram, rhs)
    qd = n_mat.T @ y
    noise_floor(n_mat, y)
    message = ""
    if not np.isfinite(qd).all():
        qd, message = np.zeros(ctrl.n), "non-finite command replaced by zero"
    if not ctrl.saturate:
        return qd, False, (), message, x, xd
    box = command_box(
        q, ctrl.qd_prev, ctrl.q_min, ctrl.q_max, ctrl.qd_max, ctrl.a_max, ctrl.period_s,
        ctrl.braking_aware,
    )  # fmt: skip
    clipped = box.project(qd)
    conflict = tuple(np.flatnonzero(box.conflict).tolist())
    return clipped, not np.array_equal(clipped, qd), conflict, message, x, xd


FLOOR = [0.0]


def noise_floor(n_mat: np.ndarray, y: np.ndarray) -> None:
    """The rounding floor ``eps |N| |y|`` of ``qd = Nᵀ y``, ``y = (N Nᵀ + λ² I)⁻¹ rhs``
    (stored in ``FLOOR[0]``).

    ``N`` has rank ≤ 6 (a unit dual quaternion has 6 degrees of freedom): the part of
    ``rhs`` outside its range (second order in the tracking error) is divided by ``λ²`` in
    ``y`` and cancelled by ``Nᵀ`` only up to rounding, and near a singularity the same
    holds for the weak directions. Two implementations that round differently differ by
    about this much: up to 1e-9 rad/s with 0.1 rad errors at λ = 1e-3, below 1e-14
    tracking the bench's circle."""
    FLOOR[0] = np.finfo(float).eps * np.linalg.norm(n_mat, 2) * np.linalg.norm(y)


class ReferenceProportional(ProportionalController):
    """The controller with :func:`reference_step` as its step."""

    def _step(self, q, qd):
        cmd, saturated, conflict, message, x, xd = reference_step(self, q)
        diag = StepDiagnostics(
            status="closed_form", saturated=saturated, conflict_joints=conflict, message=message
        )
        return StepResult(
            qd_command=cmd,
            s=1.0,
            sigma=self.sigma,
            sigma_next=self.sigma + self.period_s,
            pose=x,
            target=xd,
            diagnostics=diag,
        )


def assert_same_result(new: StepResult, ref: StepResult, floors: float = 64.0) -> None:
    """Equal results; the commands to 1e-12 (relative to 1 rad/s or more) plus ``floors``
    times the reference step's rounding floor (:func:`noise_floor`; 64 = 8², a generous
    constant of the dimension: measured differences reach 15 floors near singularities
    without clipping, for the previous implementation as for this one)."""
    scale = max(1.0, float(np.abs(ref.qd_command).max()))
    tol = 1e-12 * scale + floors * FLOOR[0]
    np.testing.assert_allclose(new.qd_command, ref.qd_command, rtol=0, atol=tol)
    np.testing.assert_allclose(new.pose, ref.pose, rtol=0, atol=1e-12)  # q may differ (delay)
    np.testing.assert_array_equal(new.target, ref.target)
    assert (new.s, new.sigma, new.sigma_next) == (ref.s, ref.sigma, ref.sigma_next)
    d_new, d_ref = new.diagnostics, ref.diagnostics
    assert d_new.status == d_ref.status == "closed_form"
    assert d_new.saturated == d_ref.saturated
    assert d_new.conflict_joints == d_ref.conflict_joints
    assert d_new.message == d_ref.message
    assert (d_new.iterations, d_new.fallback, d_new.relaxed) == (0, False, False)
    assert new.horizon_qd is None and new.horizon_s is None


# ------------------------------------------------------------------ the box


def random_box_case(rng: np.random.Generator, n: int):
    """Positions inside, near and beyond the limits, also right at the fast path's ``far``
    distance; previous commands up to 1.5 qd_max (acceleration conflicts); commands inside
    and outside the box; per-joint limits over a wide range."""
    q_min = -rng.uniform(0.5, 3.0, n)
    q_max = rng.uniform(0.5, 3.0, n)
    qd_max = np.exp(rng.uniform(np.log(0.05), np.log(10.0), n))
    a_max = np.exp(rng.uniform(np.log(0.5), np.log(100.0), n))
    period = float(rng.choice([1e-3, 4e-3, 0.01, 0.05]))
    braking = bool(rng.random() < 0.8)
    reach = period * qd_max + (qd_max**2 / (2 * a_max) if braking else 0.0)
    mode = rng.integers(0, 4, n)
    side = rng.random(n) < 0.5
    dist = np.where(
        mode == 0,
        rng.uniform(-0.1, 0.2, n),  # near or beyond a limit
        np.where(mode == 1, reach * (1.0 + rng.uniform(-1e-5, 1e-5, n)), 0.0),  # at `far`
    )
    q = np.where(side, q_max - dist, q_min + dist)
    q = np.where(mode >= 2, rng.uniform(q_min, q_max), q)
    qd_prev = rng.uniform(-1.5, 1.5, n) * qd_max
    qd = rng.uniform(-2.0, 2.0, n) * qd_max
    return q, qd, qd_prev, q_min, q_max, qd_max, a_max, period, braking


def limits(a_max: np.ndarray, period: float) -> list[tuple[float, ...]]:
    """``(a T, 2 a, (a T)², T a)`` per joint, as the controller builds them."""
    at, two_a, at2 = braking_constants(a_max, period)
    step = (period * a_max).tolist()
    return list(zip(at.tolist(), two_a.tolist(), at2.tolist(), step, strict=True))


@pytest.mark.parametrize("n", [1, 5, 7, 12])
def test_clip_to_box_equals_command_box_bit_for_bit(n):
    rng = np.random.default_rng(20240607 + n)
    seen = {"saturated": 0, "conflict": 0, "beyond": 0}
    for _ in range(3000):
        q, qd, qd_prev, q_min, q_max, qd_max, a_max, period, braking = random_box_case(rng, n)
        box = command_box(q, qd_prev, q_min, q_max, qd_max, a_max, period, braking)
        expected = box.project(qd)
        consts = joint_constants(limits(a_max, period), qd_max.tolist(), period, braking)
        got, saturated, conflict = prop._clip_to_box(
            qd, q, qd_prev, q_min, q_max, qd_max, a_max, period, np.array(consts), braking
        )
        np.testing.assert_array_equal(got, expected)
        assert saturated == (not np.array_equal(expected, qd))
        assert conflict == tuple(np.flatnonzero(box.conflict).tolist())
        if not saturated:
            assert got is qd
        seen["saturated"] += saturated
        seen["conflict"] += bool(conflict)
        seen["beyond"] += bool(np.any((q < q_min) | (q > q_max)))
    assert min(seen.values()) > 100  # every branch was exercised


def test_clip_to_box_falls_back_to_command_box():
    """Where the compiled kernel declines (a NaN previous command, which a QP could not
    take), the clip takes ``command_box`` itself."""
    q = np.array([0.0, 1.0, -0.5])
    q_min, q_max = np.full(3, -2.0), np.full(3, 2.0)
    qd_max = np.array([1.0, 3.0, 2.0])
    a_max = np.array([10.0, 10.0, 0.1])
    qd_prev = np.array([0.5, np.nan, 0.0])
    qd = np.array([2.0, 5.0, -1.0])
    consts = joint_constants(limits(a_max, 1e-3), qd_max.tolist(), 1e-3, True)
    bounds, flags = np.empty((2, 3)), np.empty(3, dtype=np.int8)
    assert joint_boxes(q, qd_prev, q_min, q_max, np.array(consts), 1e-3, True, bounds, flags) < 0
    got, saturated, conflict = prop._clip_to_box(
        qd, q, qd_prev, q_min, q_max, qd_max, a_max, 1e-3, np.array(consts), True
    )
    box = command_box(q, qd_prev, q_min, q_max, qd_max, a_max, 1e-3, True)
    np.testing.assert_array_equal(got, box.project(qd))
    assert saturated and conflict == tuple(np.flatnonzero(box.conflict).tolist())


def test_far_distance_is_verified_and_conservative():
    rng = np.random.default_rng(7)
    for braking in (True, False):
        qd_max = np.exp(rng.uniform(np.log(1e-3), np.log(50.0), 2000))
        a_max = np.exp(rng.uniform(np.log(1e-2), np.log(1e3), 2000))
        for period in (1e-4, 1e-3, 0.05):
            consts = joint_constants(limits(a_max, period), qd_max.tolist(), period, braking)
            for v, far, at, two_a, at2, _ in consts:
                assert math.isfinite(far)
                assert far / period >= v
                if braking:
                    assert math.sqrt(far * two_a + at2) - at >= v
    # an unverifiable case (overflow) disables the shortcut instead of using it
    consts = joint_constants(limits(np.array([1e-300]), 1.0), [1e300], 1.0, True)
    assert consts[0][1] == math.inf


# ------------------------------------------------------------------ the whole step


def make(robot, traj, period=1e-3, cls=ProportionalController, **kw):
    if robot.nq == 7:
        kw.setdefault("velocity_limits", THESIS_VEL)
    kw.setdefault("acceleration_limit", 10.0)
    return cls(robot, traj, period, **kw)


CONFIGS = [
    {},
    {"braking_aware": False},
    {"saturate": False},
    {"gain_per_s": 40.0, "damping": 0.05, "acceleration_limit": 3.0},
    {"measurement_delay_periods": 2, "position_margin_rad": 0.0},
]


@pytest.mark.parametrize("cfg", CONFIGS)
@pytest.mark.parametrize("spread", [0.01, 0.3])
def test_step_equals_reference_on_random_states(lbr4p, cfg, spread):
    """``spread``: how far the measured ``q`` is from the anchor (the tracking error); at
    0.3 rad the rounding floor reaches 1e-10 (the previous implementation differed from
    this reference by as much)."""
    rng = np.random.default_rng(11)
    new = make(lbr4p, Circle(2.0), **cfg)
    ref = make(lbr4p, Circle(2.0), cls=ReferenceProportional, **cfg)
    lim = lbr4p.limits
    saturated = 0
    for _ in range(300):
        q0 = rng.uniform(lim.q_min, lim.q_max)
        q = np.clip(q0 + rng.normal(0.0, spread, 7), lim.q_min - 0.02, lim.q_max + 0.02)
        qd0 = rng.uniform(-1.2, 1.2, 7) * THESIS_VEL
        sigma = float(rng.uniform(0.0, 2.5))  # also past T_tot (target held, derivative 0)
        for ctrl in (new, ref):
            ctrl.reset(q0, qd0, sigma)
        r_new, r_ref = new.step(q), ref.step(q)
        assert_same_result(r_new, r_ref)
        saturated += r_ref.diagnostics.saturated
    if cfg.get("saturate", True):
        assert saturated > 30


@pytest.mark.parametrize(
    ("traj", "period", "steps", "cfg", "floors"),
    [
        (Circle(2.0), 1e-3, 2300, {}, 0.0),  # the bench's loop, past T_tot: flat 1e-12
        (Circle(1.0), 1e-3, 1200, {"gain_per_s": 30.0}, 64.0),  # large errors, saturates
        (Sinusoid(4.0), 0.01, 450, {"braking_aware": False}, 64.0),
        (Circle(2.0), 4e-3, 600, {"measurement_delay_periods": 2}, 64.0),
    ],
)
def test_closed_loop_equals_reference(lbr4p, traj, period, steps, cfg, floors):
    new = make(lbr4p, traj, period, **cfg)
    ref = make(lbr4p, traj, period, cls=ReferenceProportional, **cfg)
    q = LBR4P_Q0.copy()
    new.reset(q)
    ref.reset(q)
    q_ref = q.copy()  # the reference's own, independent loop
    ref_alone = make(lbr4p, traj, period, cls=ReferenceProportional, **cfg)
    ref_alone.reset(q_ref)
    for _ in range(steps):
        r_new, r_ref = new.step(q), ref.step(q)
        assert_same_result(r_new, r_ref, floors)
        q = q + period * r_new.qd_command
        q_ref = q_ref + period * ref_alone.step(q_ref).qd_command
    if floors == 0.0:  # where the floor is large, the two runs drift apart by ~1e-8
        np.testing.assert_allclose(q, q_ref, rtol=0, atol=1e-11)


@pytest.mark.parametrize("n", [1, 5, 10])
def test_other_joint_counts(n):
    robot = RobotModel.from_urdf(long_chain_urdf(n), "flange")
    rng = np.random.default_rng(n)
    q = rng.uniform(-0.5, 0.5, n)
    new, ref = make(robot, Circle(2.0)), make(robot, Circle(2.0), cls=ReferenceProportional)
    new.reset(q)
    ref.reset(q)
    for _ in range(400):
        r_new, r_ref = new.step(q), ref.step(q)
        assert_same_result(r_new, r_ref)
        q = q + 1e-3 * r_new.qd_command


def test_parameters_changed_after_construction_are_used(lbr4p):
    """K, qd_max, q_min/q_max (faults.analysis.position_margin sets them) and T are read at
    every step, as before; the cached constants follow them."""
    rng = np.random.default_rng(3)
    new = make(lbr4p, Circle(2.0))
    ref = make(lbr4p, Circle(2.0), cls=ReferenceProportional)
    lim = lbr4p.limits
    for change in range(4):
        for ctrl in (new, ref):
            if change == 0:
                ctrl.gain_per_s = 25.0
            elif change == 1:
                ctrl.qd_max = 0.5 * THESIS_VEL
            elif change == 2:
                ctrl.q_min, ctrl.q_max = lim.q_min + 0.3, lim.q_max - 0.3
            else:
                ctrl.qd_max[2] = 0.1  # in place
        for _ in range(50):
            q0 = rng.uniform(lim.q_min, lim.q_max)
            q = q0 + rng.normal(0.0, 0.1, 7)
            qd0 = rng.uniform(-1.0, 1.0, 7)
            for ctrl in (new, ref):
                ctrl.reset(q0, qd0, 0.5)
            assert_same_result(new.step(q), ref.step(q))


def test_cholesky_solve_equals_lu_and_falls_back():
    rng = np.random.default_rng(1)
    n_mat = rng.normal(size=(8, 7))
    gram = n_mat @ n_mat.T + 1e-6 * np.eye(8)
    rhs = rng.normal(size=8)
    np.testing.assert_allclose(prop._solve_spd(gram, rhs), np.linalg.solve(gram, rhs), rtol=1e-9)
    indefinite = np.diag([1.0, -1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0])
    np.testing.assert_allclose(prop._solve_spd(indefinite, rhs), np.linalg.solve(indefinite, rhs))


def test_non_finite_command_replaced_by_zero(lbr4p, monkeypatch):
    ctrl = make(lbr4p, Circle(2.0))
    ctrl.reset(LBR4P_Q0)
    monkeypatch.setattr(prop, "_solve_spd", lambda gram, rhs: np.full(8, np.nan))
    res = ctrl.step(LBR4P_Q0)
    np.testing.assert_array_equal(res.qd_command, np.zeros(7))
    assert res.diagnostics.message == "non-finite command replaced by zero"
    assert np.isfinite(res.qd_command).all()


# ------------------------------------------------------------------ closed-loop behaviour


def test_proportional_converges_exponentially_to_a_fixed_pose(lbr4p):
    x0 = lbr4p.pose(LBR4P_Q0)
    offset = dq_from_rt(qfrom_axis_angle([0, 0, 1], 0.2), np.array([0.03, -0.02, 0.04]))
    goal = dq_mul(x0, offset)
    traj = FunctionTrajectory(lambda s: goal, lambda s: np.zeros(8), 3.0, reference=np.eye(8)[0])
    k_gain = 5.0
    ctrl = ProportionalController(lbr4p, traj, 0.01, gain_per_s=k_gain, velocity_limits=THESIS_VEL,
                                  acceleration_limit=100.0)  # fmt: skip
    res = run_kinematic(ctrl, LBR4P_Q0)
    err = np.linalg.norm(res.log.target - res.log.pose, axis=1)
    # e_{k+1} ≈ (1 - T K) e_k: log-linear decay at rate K while unsaturated
    k = np.arange(err.size)
    mid = (err < err[0] * 0.5) & (err > 1e-6)
    slope = np.polyfit(k[mid] * 0.01, np.log(err[mid]), 1)[0]
    assert slope == pytest.approx(-k_gain, rel=0.1)
    assert err[-1] < 1e-5


#: The thesis's period (Table 1) for the closed-loop behaviour below.
T_THESIS = 0.05


def test_proportional_tracks_a_feasible_circle(lbr4p):
    res = run_kinematic(make(lbr4p, Circle(8.0), T_THESIS), LBR4P_Q0)
    assert res.metrics.completed and res.metrics.e_mean < 5e-4
    assert res.metrics.path_deviation_max_m < 1e-3


def test_whole_run_has_no_violation(lbr4p):
    res = run_kinematic(make(lbr4p, Circle(1.0), T_THESIS), LBR4P_Q0)
    m = res.metrics
    assert (m.position_violations, m.velocity_violations, m.acceleration_violations) == (0, 0, 0)
    assert not m.nan_seen


def test_varying_orientation_is_tracked(lbr4p):
    traj = turning_waypoints()
    assert_tracked_and_turned(run_kinematic(make(lbr4p, traj, T_THESIS), LBR4P_Q0))
