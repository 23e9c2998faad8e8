"""Benchmarks of the control step (``dqcontrol bench``, ``benchmarks/bench_controllers.py``).

Figures are medians (and 99th percentiles) of per-step wall times measured inside a real
closed loop (kinematic, LBR4p, circle), so every step sees a changing state, a changing
active set and the warm start a real loop gives it. Peers are measured in the same run and
reported as ratios: DQ Robotics's ``fkm`` + ``pose_jacobian`` and its
``DQ_ClassicQPController`` step (a local QP without scaling; its QP solved by quadprog
through DQ Robotics's Python solver interface), when the ``dqrobotics`` package is present.
"""

from __future__ import annotations

import json
import os
import platform
import time
import timeit
from pathlib import Path

import numpy as np

from dqcontrol.controllers import (
    LocalController,
    PredictiveController,
    PredictiveNoScalingController,
    ProportionalController,
)
from dqcontrol.model import LBR4P_Q0, RobotModel, load_lbr4p
from dqcontrol.trajectories import Circle

__all__ = ["bench_controllers", "bench_dqrobotics", "bench_kinematics", "long_chain_urdf", "main"]

THESIS_VEL = np.pi * np.array([1, 1, 1, 1, 2.5, 2.5, 2.5])
LBR4P_DH = {
    "d": [0.2, 0, 0.4, 0, 0.39, 0, 0.078],
    "alpha": [np.pi / 2, -np.pi / 2, np.pi / 2, -np.pi / 2, np.pi / 2, -np.pi / 2, 0],
}


def _median_us(fn, number: int, repeat: int = 7) -> float:
    return float(np.median(timeit.repeat(fn, number=number, repeat=repeat)) / number * 1e6)


def _make(kind: str, robot: RobotModel, traj, period_s: float, solver: str, p: int = 10):
    n = robot.nq
    vel = THESIS_VEL if n == 7 else np.full(n, np.pi)
    kw = {"velocity_limits": vel, "acceleration_limit": 10.0}
    if kind == "proportional":
        return ProportionalController(robot, traj, period_s, **kw)
    if kind == "local":
        return LocalController(robot, traj, period_s, solver=solver, **kw)
    if kind == "noscale":
        return PredictiveNoScalingController(
            robot, traj, period_s, num_instants=p, solver=solver, **kw
        )
    return PredictiveController(robot, traj, period_s, num_instants=p, solver=solver, **kw)


def step_times(controller, q0: np.ndarray, steps: int) -> dict:
    """Per-step wall time [µs] over a kinematic closed loop (median, p99, solver median)."""
    q = np.array(q0, dtype=float)
    controller.reset(q)
    times, solves, iters = [], [], []
    for _ in range(steps):
        t0 = time.perf_counter()
        res = controller.step(q)
        times.append(time.perf_counter() - t0)
        solves.append(res.diagnostics.solve_time_s)
        iters.append(res.diagnostics.iterations)
        q = q + controller.period_s * res.qd_command
        if controller.done:
            controller.reset(q)
    t = np.array(times) * 1e6
    return {
        "median_us": float(np.median(t)),
        "p99_us": float(np.percentile(t, 99)),
        "p99_over_median": float(np.percentile(t, 99) / np.median(t)),
        "solver_median_us": float(np.median(solves) * 1e6),
        "iterations_median": float(np.median(iters)),
        "steps": steps,
    }


def bench_controllers(steps: int = 300, period_s: float = 0.05) -> dict:
    """Step times of every controller on the LBR4p (circle T_tot = 2 s), both QP backends."""
    robot = load_lbr4p()
    out: dict = {}
    for solver in ("osqp", "daqp"):
        for kind, p in (("local", 1), ("predictive", 6), ("predictive", 10), ("noscale", 10)):
            name = kind if kind == "local" else f"{kind}_p{p}"
            ctrl = _make(kind, robot, Circle(2.0), period_s, solver, p)
            out[f"{name}[{solver}]"] = step_times(ctrl, LBR4P_Q0, steps)
    out["proportional"] = step_times(
        _make("proportional", robot, Circle(2.0), period_s, "osqp"), LBR4P_Q0, steps
    )
    return out


def bench_scaling(steps: int = 120, solver: str = "daqp") -> dict:
    """Predictive step time against p (2…20) on the LBR4p, and against the joint count."""
    robot = load_lbr4p()
    by_p = {}
    for p in (2, 4, 6, 10, 14, 20):
        ctrl = _make("predictive", robot, Circle(2.0), 0.05, solver, p)
        by_p[p] = step_times(ctrl, LBR4P_Q0, steps)["median_us"]
    by_n = {}
    for n in (7, 14):
        rob = robot if n == 7 else RobotModel.from_urdf(long_chain_urdf(n), "flange")
        q0 = LBR4P_Q0 if n == 7 else np.tile(LBR4P_Q0 * 0.5, n // 7)
        ctrl = _make("predictive", rob, Circle(2.0), 0.05, solver, 10)
        by_n[n] = step_times(ctrl, q0, steps)["median_us"]
    return {"median_us_by_p": by_p, "median_us_by_joints_p10": by_n, "solver": solver}


def long_chain_urdf(n: int) -> str:
    """A serial chain of ``n`` revolute joints alternating z/y axes (for scaling figures)."""
    links = ['<link name="base"/>']
    joints = []
    parent = "base"
    for i in range(n):
        axis = "0 0 1" if i % 2 == 0 else "0 -1 0"
        links.append(
            f'<link name="l{i}"><inertial><mass value="1"/>'
            '<inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>'
        )
        z = 0.2 if i else 0.3
        joints.append(
            f'<joint name="j{i}" type="revolute"><parent link="{parent}"/><child link="l{i}"/>'
            f'<origin xyz="0 0 {z}"/><axis xyz="{axis}"/>'
            '<limit lower="-2.9" upper="2.9" effort="100" velocity="3"/></joint>'
        )
        parent = f"l{i}"
    links.append('<link name="flange"/>')
    joints.append(
        f'<joint name="jf" type="fixed"><parent link="{parent}"/><child link="flange"/>'
        '<origin xyz="0 0 0.08"/></joint>'
    )
    return '<robot name="chain">' + "".join(links + joints) + "</robot>"


def bench_kinematics() -> dict:
    """Pose + pose Jacobian of the LBR4p, single and batched (p = 10) [µs]."""
    robot = load_lbr4p()
    rng = np.random.default_rng(0)
    q = LBR4P_Q0 + rng.uniform(-0.1, 0.1, 7)
    qs = LBR4P_Q0 + rng.uniform(-0.3, 0.3, (10, 7))
    return {
        "single_us": _median_us(lambda: robot._pose_and_jacobian(q), 5000),
        "batch10_us": _median_us(lambda: robot._poses_and_jacobians(qs), 1000),
    }


def bench_dqrobotics() -> dict | None:
    """DQ Robotics peers measured in this run, or ``None`` if the package is missing."""
    try:
        import quadprog
        from dqrobotics import E_, k_
        from dqrobotics.robot_control import ControlObjective, DQ_ClassicQPController
        from dqrobotics.robot_modeling import DQ_SerialManipulatorDH
        from dqrobotics.solvers import DQ_QuadraticProgrammingSolver
    except ImportError:
        return None
    dh = np.array([np.zeros(7), LBR4P_DH["d"], np.zeros(7), LBR4P_DH["alpha"], np.zeros(7)])
    arm = DQ_SerialManipulatorDH(dh)
    base = 1 + E_ * 0.5 * 0.51 * k_
    arm.set_base_frame(base)
    arm.set_reference_frame(base)

    class QuadprogSolver(DQ_QuadraticProgrammingSolver):
        def __init__(self) -> None:
            DQ_QuadraticProgrammingSolver.__init__(self)

        def solve_quadratic_program(self, h, f, a, b, aeq, beq):
            h = 0.5 * (h + h.T) + 1e-12 * np.eye(h.shape[0])
            f, b = np.ravel(f), np.ravel(b)
            if a.size:
                return quadprog.solve_qp(h, -f, -a.T, -b)[0]
            return quadprog.solve_qp(h, -f)[0]

    solver = QuadprogSolver()
    ctrl = DQ_ClassicQPController(arm, solver)
    ctrl.set_gain(10.0)
    ctrl.set_damping(1e-3)
    ctrl.set_control_objective(ControlObjective.Pose)
    ctrl.set_inequality_constraint(
        np.vstack([np.eye(7), -np.eye(7)]), np.concatenate([THESIS_VEL, THESIS_VEL])
    )
    q = LBR4P_Q0.copy()
    target = (arm.fkm(q) * (1 + E_ * 0.5 * 0.01 * k_)).vec8()

    def kin() -> None:
        arm.fkm(q)
        arm.pose_jacobian(q)

    return {
        "fkm_pose_jacobian_us": _median_us(kin, 5000),
        "classic_qp_step_us": _median_us(
            lambda: ctrl.compute_setpoint_control_signal(q, target), 500
        ),
    }


def run_all(quick: bool = False) -> dict:
    """Every figure of the benchmark, with peer ratios and the machine."""
    steps = 60 if quick else 300
    out = {
        "machine": {
            "platform": platform.platform(),
            "processor": platform.processor() or platform.machine(),
            "cpus": os.cpu_count(),
            "python": platform.python_version(),
        },
        "kinematics": bench_kinematics(),
        "controllers": bench_controllers(steps=steps),
    }
    if not quick:
        out["scaling"] = bench_scaling()
    peers = bench_dqrobotics()
    out["dqrobotics"] = peers
    if peers:
        kin = out["kinematics"]
        ctl = out["controllers"]
        out["ratios"] = {
            "single_kinematics_vs_dqr": kin["single_us"] / peers["fkm_pose_jacobian_us"],
            "batch10_vs_10x_dqr": kin["batch10_us"] / (10 * peers["fkm_pose_jacobian_us"]),
            "local_step_vs_dqr_classic_qp": min(
                ctl["local[osqp]"]["median_us"], ctl["local[daqp]"]["median_us"]
            )
            / peers["classic_qp_step_us"],
        }
    return out


def format_report(res: dict) -> str:
    """Human-readable table of :func:`run_all`'s figures."""
    lines = [f"machine: {res['machine']}", "", "kinematics (LBR4p) [µs, median]"]
    for k, v in res["kinematics"].items():
        lines.append(f"  {k:28s} {v:9.1f}")
    lines += ["", f"{'control step (LBR4p, T = 50 ms)':40s} {'median':>9s} {'p99':>9s} "
              f"{'p99/med':>8s} {'solver':>9s} {'iters':>6s}  [µs]"]  # fmt: skip
    for k, v in res["controllers"].items():
        lines.append(
            f"  {k:38s} {v['median_us']:9.1f} {v['p99_us']:9.1f} {v['p99_over_median']:8.2f} "
            f"{v['solver_median_us']:9.1f} {v['iterations_median']:6.0f}"
        )
    if "scaling" in res:
        sc = res["scaling"]
        lines += ["", f"predictive step vs p ({sc['solver']}) [µs]: {sc['median_us_by_p']}"]
        lines.append(f"predictive p=10 vs joints [µs]: {sc['median_us_by_joints_p10']}")
    if res.get("dqrobotics"):
        lines += ["", f"DQ Robotics (same run) [µs]: {res['dqrobotics']}"]
        lines += [f"ratios: {json.dumps({k: round(v, 3) for k, v in res['ratios'].items()})}"]
    else:
        lines += ["", "DQ Robotics not installed: no peer ratios (pip install dqrobotics)"]
    return "\n".join(lines)


def main(out: str | os.PathLike | None = "results/bench.json", quick: bool = False) -> dict:
    """Run, print and (atomically) write ``results/bench.json``."""
    res = run_all(quick=quick)
    print(format_report(res))
    if out:
        path = Path(out)
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(path.suffix + ".tmp")
        tmp.write_text(json.dumps(res, indent=2))
        os.replace(tmp, path)
        print(f"\nwritten: {path}")
    return res
