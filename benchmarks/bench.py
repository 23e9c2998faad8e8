"""Benchmarks of the control step (``dqcontrol bench``, ``python benchmarks/bench.py``).

This file lives in the source repository, not in the package: ``dqcontrol bench`` loads it
from the ``benchmarks/`` folder beside the installed package (an editable install of a
checkout), and says so when there is none. Controllers are built through
:mod:`dqcontrol.registry`, with the thesis's bounds of :mod:`dqcontrol.experiments.thesis`.

Every performance figure in one run, on the machine it runs on:

- the step time of the four controllers at ``T = 1 ms`` (local with scaling, predictive
  p = 6 and p = 10 with scaling and p = 10 without, proportional), prediction, QP build
  and solve included: medians and 99th percentiles of per-step wall times measured inside
  a real closed loop (kinematic, LBR4p, the 2 s circle), so every step sees a changing
  state, a changing active set and the warm start a real loop gives it; both QP backends,
  with the solver's own time beside. The loops hold one BLAS thread for their length, as
  :func:`~dqcontrol.sim.run_loop` does (the path-following step at p = 10 is also timed
  without, each step switching the libraries itself);
- the peers, measured in the same run and reported as ratios: DQ Robotics's
  ``DQ_ClassicQPController`` step (a local QP without scaling, its QP solved by quadprog
  through DQ Robotics's Python solver interface) against our local step, and ten of its
  ``fkm`` + ``pose_jacobian`` calls against our batched kinematics of 10 configurations;
- how far the two backends' applied commands differ over a run (equal accuracy);
- the MuJoCo closed loop, predictive p = 10 at ``T = 1 ms`` on the 2 s circle: its
  real-time factor (simulated time / wall time);
- the step time against p (2 … 20) and against the number of joints.

Each target is printed as met or not met beside its figure. Timings are
medians over repeated runs; the machine is shared, so they move by ±10–20 % between runs.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import math
import os
import platform
import time
import timeit
from importlib import metadata
from pathlib import Path

import numpy as np

from dqcontrol.controllers import single_blas_thread
from dqcontrol.controllers.thesis.controller import DEFAULT_SOLVER
from dqcontrol.experiments.thesis import THESIS_ACCELERATION_LIMIT, THESIS_VELOCITY_LIMITS
from dqcontrol.model import LBR4P_Q0, RobotModel, load_lbr4p
from dqcontrol.registry import build_controller
from dqcontrol.trajectories import Circle

__all__ = [
    "TARGETS",
    "bench_agreement",
    "bench_controllers",
    "bench_dqrobotics",
    "bench_kinematics",
    "bench_mujoco",
    "bench_run_log",
    "bench_scaling",
    "format_report",
    "long_chain_urdf",
    "machine",
    "main",
    "run_all",
    "step_times",
]

THESIS_VEL = np.array(THESIS_VELOCITY_LIMITS)
LBR4P_DH = {
    "d": [0.2, 0, 0.4, 0, 0.39, 0, 0.078],
    "alpha": [np.pi / 2, -np.pi / 2, np.pi / 2, -np.pi / 2, np.pi / 2, -np.pi / 2, 0],
}
#: Control period of the step figures [s] (1 kHz).
PERIOD_S = 0.001
#: The performance targets: (figure, comparison, bound, unit).
TARGETS: dict[str, tuple[str, str, float, str]] = {
    "local": ("local step (scaling), median", "<=", 100.0, "µs"),
    "predictive_p6": ("predictive p = 6 step, median", "<=", 300.0, "µs"),
    "predictive_p10": ("predictive p = 10 step, median", "<=", 500.0, "µs"),
    "proportional": ("proportional step, median", "<=", 50.0, "µs"),
    "p99_over_median": ("99th percentile / median (worst of the four)", "<=", 2.0, "×"),
    "local_vs_dqr_classic_qp": ("local step / DQR ClassicQP step", "<=", 1.0, "×"),
    "batch10_vs_10x_dqr": ("batched kinematics p=10 / 10 DQR fkm+J", "<=", 0.5, "×"),
    "mujoco_realtime_factor": ("MuJoCo p=10, T=1 ms: sim time / wall time", ">=", 1.0, "×"),
    "path_following_p10": ("path-following p = 10 step, median", "<=", 300.0, "µs"),
    "run_log_per_sample": ("streamed run log at 1 kHz: cost per sample, median", "<=", 5.0, "µs"),
    "path_following_p99": ("path-following p = 10: p99 / median", "<=", 2.0, "×"),
    "path_following_step_over_solve": (
        "path-following p = 10: step / prioritised solve",
        "<=",
        2.0,
        "×",
    ),  # fmt: skip
    "path_following_collision": (
        "path-following p = 10 with the collision limit, median",
        "<=",
        500.0,
        "µs",
    ),  # fmt: skip
}
STEP_KINDS = (("local", 1), ("predictive", 6), ("predictive", 10), ("noscale", 10))


def _median_us(fn, number: int, repeat: int = 7) -> float:
    return float(np.median(timeit.repeat(fn, number=number, repeat=repeat)) / number * 1e6)


def _version(dist: str) -> str | None:
    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        return None


def machine() -> dict:
    """CPU model, cores, Python and the versions of the packages that set the figures."""
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as fh:
            for line in fh:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    packages = ("dqcontrol", "numpy", "scipy", "pin", "daqp", "osqp", "mujoco", "dqrobotics")
    return {
        "cpu": cpu,
        "cores": os.cpu_count(),
        "platform": platform.platform(),
        "python": platform.python_version(),
        "packages": {name: _version(name) for name in packages},
    }


#: The registry's name of each kind of :data:`STEP_KINDS` (``{p}``: its count).
_REGISTRY_NAMES = {"local": "local", "predictive": "p{p}", "noscale": "noscale{p}"}


def _make(kind: str, robot: RobotModel, traj, period_s: float, solver: str | None, p: int = 10):
    """A controller of the registry with the thesis's bounds (π rad/s for other arms)."""
    n = robot.nq
    vel = THESIS_VEL if n == 7 else np.full(n, np.pi)
    shared = {"velocity_limits": vel, "acceleration_limit": THESIS_ACCELERATION_LIMIT}
    shared["solver"] = solver
    name = _REGISTRY_NAMES.get(kind, kind).format(p=p)
    return build_controller(name, robot, traj, period_s, shared=shared)


def _name(kind: str, p: int) -> str:
    """The controller's own ``name`` (``local``, ``predictive_p10``, ``predictive_noscale_p10``)."""
    if kind in ("local", "proportional"):
        return kind
    return f"predictive_noscale_p{p}" if kind == "noscale" else f"{kind}_p{p}"


_REFERENCE_ARRAY = np.eye(8)


def _reference_work(count: int) -> None:
    """A constant workload: ``count`` 8×8 numpy products (the size of a step's calls)."""
    a = _REFERENCE_ARRAY
    for _ in range(count):
        a.dot(a)


def _reference_count(target_s: float) -> int:
    """How many products :func:`_reference_work` needs to take about ``target_s``."""
    unit = float(np.median(timeit.repeat(lambda: _reference_work(100), number=1, repeat=21)))
    return max(1, round(100 * target_s / unit))


def step_times(
    controller,
    q0: np.ndarray,
    steps: int,
    repeats: int = 1,
    reference: bool = True,
    held: bool = True,
) -> dict:
    """Per-step wall time [µs] over ``repeats`` kinematic closed loops of ``steps`` steps,
    each loop holding one BLAS thread as :func:`~dqcontrol.sim.run_loop` does (``held``;
    else every step switches the libraries itself).

    Median, 99th percentile and their ratio over all steps pooled; the solver's median
    time; and the spread of the runs' medians. With ``reference``, every step is followed
    by a constant workload calibrated to the step's median (a warm-up of 100 steps) and
    timed the same way: its p99/median is this host's own floor at that duration
    (interruptions of a shared VM), against which the controller's is to be read.

    The repeated runs are the same closed loop (same start, the controller reset): step k
    does the same work in each, and they end in the same state bit for bit (checked). The
    p99/median of each step's fastest time over the runs (``own_p99_over_median``, with
    ``repeats ≥ 2``) is then the variation of the code's own work (active-set changes,
    iterations), with the host's interruptions removed unless one hits the same step in
    every run: on this 2-core VM three runs often leave some (the proportional step, the
    same work at every step, gave 1.6 with three, 1.05 with five).
    """
    count = 0
    if reference:
        warm = step_times(controller, q0, min(steps, 100), 1, reference=False, held=held)
        count = _reference_count(warm["median_us"] * 1e-6)
    times, run_medians, ref_times, runs, finals = [], [], [], [], []
    diag: dict[str, list] = {"solve": [], "levels": [], "iters": [], "rounds": []}
    for _ in range(repeats):
        with single_blas_thread() if held else contextlib.nullcontext():
            run, q = _closed_loop(controller, q0, steps, count, ref_times, diag)
        times += run
        runs.append(run)
        finals.append(q)
        run_medians.append(float(np.median(run) * 1e6))
    t = np.array(times) * 1e6
    out = {
        "median_us": float(np.median(t)),
        "p99_us": float(np.percentile(t, 99)),
        "p99_over_median": float(np.percentile(t, 99) / np.median(t)),
        "solver_median_us": float(np.median(diag["solve"]) * 1e6),
        "levels_median_us": float(np.median(diag["levels"]) * 1e6),
        "iterations_median": float(np.median(diag["iters"])),
        "linearisations_mean": float(np.mean(diag["rounds"])),
        "linearisations_max": int(np.max(diag["rounds"])),
        "run_medians_us": run_medians,
        "steps": steps * repeats,
    }
    if repeats >= 2 and all(np.array_equal(finals[0], f) for f in finals[1:]):
        own = np.min(np.array(runs), axis=0)
        out["own_p99_over_median"] = float(np.percentile(own, 99) / np.median(own))
    if ref_times:
        r = np.array(ref_times) * 1e6
        out["reference_median_us"] = float(np.median(r))
        out["reference_p99_over_median"] = float(np.percentile(r, 99) / np.median(r))
    return out


def _closed_loop(
    controller, q0: np.ndarray, steps: int, count: int, ref_times: list, diag: dict
) -> tuple[list[float], np.ndarray]:
    """One kinematic closed loop of ``steps`` steps from ``q0`` (the controller reset): each
    step's wall time [s] and the last state; the reference workload of ``count`` products
    after each step (its times to ``ref_times``), each step's diagnostics to ``diag``."""
    q = np.array(q0, dtype=float)
    controller.reset(q)
    run = []
    for _ in range(steps):
        t0 = time.perf_counter()
        res = controller.step(q)
        run.append(time.perf_counter() - t0)
        if count:
            t0 = time.perf_counter()
            _reference_work(count)
            ref_times.append(time.perf_counter() - t0)
        d = res.diagnostics
        diag["solve"].append(d.solve_time_s)
        diag["levels"].append(d.levels_time_s)
        diag["iters"].append(d.iterations)
        diag["rounds"].append(d.linearisations)
        q = q + controller.period_s * res.qd_command
        if controller.done:
            controller.reset(q)
    return run, q


def bench_controllers(
    steps: int = 2000, repeats: int = 5, other_repeats: int = 3, period_s: float = PERIOD_S
) -> dict:
    """Step times of the four controllers on the LBR4p (circle T_tot = 2 s; the predictive
    with scaling at p = 6 and 10, without at p = 10), both backends: ``repeats`` closed
    loops with the default backend and the proportional controller (the targets; five
    leave few host interruptions in their "own" figure, see :func:`step_times`),
    ``other_repeats`` with the other backend.

    Keys ``"<controller>[<solver>]"`` and ``"proportional"``.
    """
    robot = load_lbr4p()
    out: dict = {}
    for solver in ("daqp", "osqp"):
        for kind, p in STEP_KINDS:
            ctrl = _make(kind, robot, Circle(2.0), period_s, solver, p)
            default = solver == DEFAULT_SOLVER
            out[f"{_name(kind, p)}[{solver}]"] = step_times(
                ctrl, LBR4P_Q0, steps, repeats if default else other_repeats, reference=default
            )
    ctrl = _make("proportional", robot, Circle(2.0), period_s, None)
    out["proportional"] = step_times(ctrl, LBR4P_Q0, steps, repeats)
    return out


def bench_agreement(steps: int = 2000, period_s: float = PERIOD_S) -> dict:
    """Largest difference of the applied command [rad/s] and of ``s`` between the DAQP and
    the OSQP backend over one closed loop (both controllers stepped at the same states)."""
    robot = load_lbr4p()
    out = {}
    for kind, p in STEP_KINDS:
        a = _make(kind, robot, Circle(2.0), period_s, "daqp", p)
        b = _make(kind, robot, Circle(2.0), period_s, "osqp", p)
        q = LBR4P_Q0.copy()
        a.reset(q)
        b.reset(q)
        dqd = ds = 0.0
        for _ in range(steps):
            ra, rb = a.step(q), b.step(q)
            dqd = max(dqd, float(np.abs(ra.qd_command - rb.qd_command).max()))
            ds = max(ds, abs(ra.s - rb.s))
            q = q + period_s * ra.qd_command
            if a.done:
                break
        out[_name(kind, p)] = {"max_abs_qd_diff": dqd, "max_abs_s_diff": ds}
    return out


def bench_scaling(
    steps: int = 500,
    repeats: int = 2,
    solver: str = DEFAULT_SOLVER,
    ps: tuple[int, ...] = (2, 4, 6, 8, 10, 14, 20),
    joints: tuple[int, ...] = (7, 14, 21),
    period_s: float = PERIOD_S,
) -> dict:
    """Predictive step time against p on the LBR4p, and at p = 10 against the joint count
    (the LBR4p, then :func:`long_chain_urdf` chains), with a power-law fit of each."""
    robot = load_lbr4p()
    by_p = {}
    for p in ps:
        ctrl = _make("predictive", robot, Circle(2.0), period_s, solver, p)
        res = step_times(ctrl, LBR4P_Q0, steps, repeats, reference=False)
        by_p[p] = {k: res[k] for k in ("median_us", "solver_median_us", "p99_over_median")}
    by_n = {}
    for n in joints:
        rob = robot if n == 7 else RobotModel.from_urdf(long_chain_urdf(n), "flange")
        q0 = LBR4P_Q0 if n == 7 else np.resize(LBR4P_Q0 * 0.5, n)
        ctrl = _make("predictive", rob, Circle(2.0), period_s, solver, 10)
        res = step_times(ctrl, q0, steps, repeats, reference=False)
        by_n[n] = {k: res[k] for k in ("median_us", "solver_median_us", "p99_over_median")}
    return {
        "solver": solver,
        "by_p": by_p,
        "by_joints_p10": by_n,
        "fit_p": _power_fit(by_p),
        "fit_joints": _power_fit(by_n),
    }


def bench_path_following(
    steps: int = 1000,
    repeats: int = 3,
    ps: tuple[int, ...] = (6, 10, 20),
    joints: tuple[int, ...] = (7, 14),
    period_s: float = PERIOD_S,
) -> dict:
    """The path-following controller at ``period_s``: median/p99 step and solve, DAQP
    iterations and linearise-and-solve rounds per step, against p on the LBR4p and at
    p = 10 against the joint count (:func:`long_chain_urdf` chains). At p = 10 (the
    target) the ``repeats`` closed loops of ``steps`` steps also give the host's floor
    and the code's own p99/median (:func:`step_times`), and :func:`held_against_unheld`
    the gain of holding one BLAS thread over the loop; the other figures take one loop."""
    robot = load_lbr4p()
    keys = (
        "median_us", "p99_us", "p99_over_median", "solver_median_us", "levels_median_us",
        "iterations_median", "linearisations_mean", "linearisations_max",
    )  # fmt: skip
    extra = ("reference_p99_over_median", "own_p99_over_median", "held_over_unheld")
    by_p = {}
    for p in ps:
        ctrl = _make(f"pf{p}", robot, Circle(2.0), period_s, None)
        target = p == 10
        res = step_times(ctrl, LBR4P_Q0, steps, repeats if target else 1, reference=target)
        if target:
            res.update(held_against_unheld(robot, period_s, 3 * steps))
        by_p[p] = {k: res[k] for k in keys + extra if k in res}
    by_n = {}
    for n in joints:
        rob = robot if n == 7 else RobotModel.from_urdf(long_chain_urdf(n), "flange")
        q0 = LBR4P_Q0 if n == 7 else np.resize(LBR4P_Q0 * 0.5, n)
        ctrl = _make("pf10", rob, Circle(2.0), period_s, None)
        res = step_times(ctrl, q0, max(steps // 10, 20), 1, reference=False)
        by_n[n] = {k: res[k] for k in keys}
    # the controller as the API and `dqcontrol run` give it: the dynamics-aware bound
    shared = {"velocity_limits": THESIS_VEL}
    ctrl = build_controller("pf10", robot, Circle(2.0), period_s, shared=shared)
    res = step_times(ctrl, LBR4P_Q0, steps, 1, reference=False)
    dynamics = {k: res[k] for k in keys}
    return {
        "by_p": by_p,
        "by_joints_p10": by_n,
        "fit_p": _power_fit(by_p),
        "dynamics_p10": dynamics,
    }


def held_against_unheld(robot: RobotModel, period_s: float, steps: int, block: int = 100) -> dict:
    """The path-following step (p = 10) with one BLAS thread held over the loop against the
    same step switching the libraries itself, interleaved: two identical controllers run
    the same closed loop in alternating blocks of ``block`` steps (``steps`` each, after a
    block of warm-up); the median over the block pairs of the ratio of their medians."""
    loops = [
        _local_loop_step_times(_make("pf10", robot, Circle(2.0), period_s, None), LBR4P_Q0, held)
        for held in (True, False)
    ]
    for run in loops:
        run(block)
    ratios = []
    for k in range(max(steps // block, 2)):
        order = (0, 1) if k % 2 == 0 else (1, 0)
        medians = {i: float(np.median(loops[i](block))) for i in order}
        ratios.append(medians[0] / medians[1])
    return {"held_over_unheld": float(np.median(ratios))}


def cell_obstacles(robot: RobotModel) -> tuple:
    """Three obstacles around the LBR4p's circle: a ball at the elbow, a box beside the
    path, the table under it."""
    from dqcontrol.model.collision import Box, HalfSpace, Sphere

    tool = robot.placement(LBR4P_Q0).translation
    return (
        Sphere(name="ball", position_m=(0.2245, -0.2559, 0.9519), radius_m=0.05),
        Box(name="crate", position_m=tuple(tool + [0.0, 0.25, -0.1]), size_m=(0.1, 0.1, 0.2)),
        HalfSpace(name="table", normal=(0.0, 0.0, 1.0), offset_m=float(tool[2] - 0.3)),
    )


def bench_collision(steps: int = 300, period_s: float = PERIOD_S) -> dict:
    """The collision limit's cost at ``period_s`` with three obstacles and self-collision:
    pairs, pairs within the influence distance, rows, coal distance queries and closed-form
    distances per step, the limit's own time and the whole step, for the local controller and the
    path-following one (p = 10)."""
    from dqcontrol.controllers.limits.collision import CollisionLimit
    from dqcontrol.model.collision import CollisionModel

    robot = load_lbr4p()
    model = CollisionModel(robot, cell_obstacles(robot), self_collision=True)
    shared = {"velocity_limits": THESIS_VEL, "acceleration_limit": THESIS_ACCELERATION_LIMIT}
    out: dict = {"pairs": len(model.pairs)}
    for name in ("local", "pf10"):
        limit = CollisionLimit(model)
        rows, limit_times, influence, step_times_s = [], [], [], []
        queries, closed = [], []
        timed_rows = limit.rows

        def rows_timed(ctx, _rows=timed_rows, _times=limit_times):
            t0 = time.perf_counter()
            result = _rows(ctx)
            _times.append(time.perf_counter() - t0)
            return result

        limit.rows = rows_timed
        ctrl = build_controller(
            name, robot, Circle(2.0), period_s, shared=shared, extra_limits=(limit,)
        )
        q = LBR4P_Q0.copy()
        ctrl.reset(q)
        with single_blas_thread():  # as the control loop holds it
            for _ in range(steps):
                before, before_closed = model.query_count, model.closed_form_count
                res = ctrl.step(q)
                queries.append(model.query_count - before)
                closed.append(model.closed_form_count - before_closed)
                step_times_s.append(res.diagnostics.step_time_s)
                rows.append(limit.last_rows)
                influence.append(limit.pairs_in_influence)
                q = q + period_s * res.qd_command
                if ctrl.done:
                    ctrl.reset(q)
        plain = build_controller(name, robot, Circle(2.0), period_s, shared=shared)
        without = step_times(plain, LBR4P_Q0, steps, 1, reference=False)["median_us"]
        out[name] = {
            "step_median_us": float(np.median(step_times_s) * 1e6),
            "step_without_limit_median_us": without,
            "limit_median_us": float(np.median(limit_times) * 1e6),
            "rows_mean": float(np.mean(rows)),
            "pairs_in_influence_mean": float(np.mean(influence)),
            "distance_queries_mean": float(np.mean(queries)),
            "closed_form_distances_mean": float(np.mean(closed)),
        }
    return out


def bench_collision_circle(period_s: float = PERIOD_S, max_factor: float = 3.0) -> dict:
    """The path-following controller (p = 10) with the collision limit of
    :func:`bench_collision` over the whole circle, to its end (at most ``max_factor`` times
    its duration): the steps past the obstacles, which the first steps of
    :func:`bench_collision` do not reach. Median and p99 step, the share of steps longer
    than the period (a wall-clock loop misses its deadline on those), fallbacks, and the
    smallest distance of any pair at the measured states [mm] (``None``: no pair came
    within the influence distance)."""
    from dqcontrol.controllers.limits.collision import CollisionLimit
    from dqcontrol.model.collision import CollisionModel

    robot = load_lbr4p()
    model = CollisionModel(robot, cell_obstacles(robot), self_collision=True)
    shared = {"velocity_limits": THESIS_VEL, "acceleration_limit": THESIS_ACCELERATION_LIMIT}
    limit = CollisionLimit(model)
    task = Circle(2.0)
    ctrl = build_controller("pf10", robot, task, period_s, shared=shared, extra_limits=(limit,))
    q = LBR4P_Q0.copy()
    ctrl.reset(q)
    times, fallbacks, closest = [], 0, np.inf
    with single_blas_thread():  # as the control loop holds it
        for _ in range(int(max_factor * task.duration / period_s)):
            res = ctrl.step(q)
            times.append(res.diagnostics.step_time_s)
            fallbacks += int(res.diagnostics.fallback)
            closest = min(closest, limit.last_min_distance_m)
            q = q + period_s * res.qd_command
            if ctrl.done:
                break
    t = np.array(times)
    return {
        "steps": int(t.size),
        "completed": bool(ctrl.done),
        "step_median_us": float(np.median(t) * 1e6),
        "step_p99_us": float(np.percentile(t, 99) * 1e6),
        "over_period_share": float(np.mean(t > period_s)),
        "fallbacks": fallbacks,
        "closest_mm": float(closest * 1e3) if np.isfinite(closest) else None,
    }


def _power_fit(table: dict) -> dict:
    """Exponents ``k`` of ``t ≈ a x^k`` for the whole step and for the solver alone
    (least squares in log-log over the measured points)."""
    xs = np.log([float(x) for x in table])
    out = {}
    for key in ("median_us", "solver_median_us"):
        ys = np.log([max(v[key], 1e-3) for v in table.values()])
        out[key] = float(np.polyfit(xs, ys, 1)[0]) if len(xs) > 1 else float("nan")
    return out


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


def _kinematics_inputs() -> tuple[np.ndarray, np.ndarray]:
    """One configuration and a batch of 10 near :data:`LBR4P_Q0` (seeded) [rad]."""
    rng = np.random.default_rng(0)
    q = LBR4P_Q0 + rng.uniform(-0.1, 0.1, 7)
    qs = LBR4P_Q0 + rng.uniform(-0.3, 0.3, (10, 7))
    return q, qs


def bench_kinematics(number: int = 2000, repeat: int = 9) -> dict:
    """Pose + pose Jacobian of the LBR4p, single and batched (p = 10 configurations) [µs]."""
    fast = load_lbr4p().fast
    q, qs = _kinematics_inputs()
    return {
        "single_us": _median_us(lambda: fast.pose_and_jacobian(q), number, repeat),
        "batch10_us": _median_us(lambda: fast.poses_and_jacobians(qs), number // 10, repeat),
    }


def _dqr_classic(arm, quadprog, solver_base, controller_class, objective) -> tuple:
    """``(solver, controller)``: DQ Robotics's ``DQ_ClassicQPController`` on ``arm`` with
    quadprog as its solver (gain 10, damping 1e-3, the pose, the thesis's velocity
    bounds)."""

    class QuadprogSolver(solver_base):
        def __init__(self) -> None:
            solver_base.__init__(self)

        def solve_quadratic_program(self, h, f, a, b, aeq, beq):
            h = 0.5 * (h + h.T) + 1e-12 * np.eye(h.shape[0])
            f, b = np.ravel(f), np.ravel(b)
            if a.size:
                return quadprog.solve_qp(h, -f, -a.T, -b)[0]
            return quadprog.solve_qp(h, -f)[0]

    solver = QuadprogSolver()
    ctrl = controller_class(arm, solver)
    ctrl.set_gain(10.0)
    ctrl.set_damping(1e-3)
    ctrl.set_control_objective(objective.Pose)
    ctrl.set_inequality_constraint(
        np.vstack([np.eye(7), -np.eye(7)]), np.concatenate([THESIS_VEL, THESIS_VEL])
    )
    return solver, ctrl


def _dqr_peers() -> dict | None:
    """DQ Robotics's calls on the LBR4p (the thesis's DH table), or ``None`` if missing.

    ``kin``: one ``fkm`` + ``pose_jacobian``; ``kin_ten``: ten of them on the batch's
    configurations; ``classic``: one ``DQ_ClassicQPController`` step (quadprog)."""
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

    solver, ctrl = _dqr_classic(
        arm, quadprog, DQ_QuadraticProgrammingSolver, DQ_ClassicQPController, ControlObjective
    )
    q, qs = _kinematics_inputs()
    target = (arm.fkm(q) * (1 + E_ * 0.5 * 0.01 * k_)).vec8()
    fkm, jac = arm.fkm, arm.pose_jacobian

    def kin() -> None:
        fkm(q)
        jac(q)

    def kin_ten() -> None:
        for qi in qs:
            fkm(qi)
            jac(qi)

    def classic() -> None:
        ctrl.compute_setpoint_control_signal(q, target)

    return {
        "version": _version("dqrobotics"),
        "kin": kin,
        "kin_ten": kin_ten,
        "classic": classic,
        # the C++ controller holds the Python solver by a raw reference: keep both alive
        "_keep": (arm, solver, ctrl),
    }


def _local_loop_step_times(controller, q0: np.ndarray, held: bool = True):
    """A function timing the next ``k`` steps of a closed kinematic loop [s each], holding one
    BLAS thread over them as the control loop does (``held``)."""
    state = {"q": np.array(q0, dtype=float)}
    controller.reset(state["q"])

    def run(k: int) -> list[float]:
        times = []
        q = state["q"]
        with single_blas_thread() if held else contextlib.nullcontext():
            for _ in range(k):
                t0 = time.perf_counter()
                res = controller.step(q)
                times.append(time.perf_counter() - t0)
                q = q + controller.period_s * res.qd_command
                if controller.done:
                    q = np.array(q0, dtype=float)
                    controller.reset(q)
        state["q"] = q
        return times

    return run


def bench_dqrobotics(number: int = 2000, rounds: int = 15) -> dict | None:
    """DQ Robotics peers and our ratios to them, or ``None`` if the package is missing.

    The machine's speed drifts by up to 2× over tens of seconds (shared VM), so each ratio
    is measured in ``rounds`` short rounds that time ours and the peer back to back; the
    ratio reported is the median of the rounds' ratios (and each time the median of its
    rounds). Our local step is timed step by step inside a closed loop (as
    :func:`step_times`); DQ Robotics's controller step is timed on a fixed set-point, its
    easiest case.
    """
    peers = _dqr_peers()
    if peers is None:
        return None
    robot = load_lbr4p()
    q, qs = _kinematics_inputs()
    loop = _local_loop_step_times(
        _make("local", robot, Circle(2.0), PERIOD_S, DEFAULT_SOLVER), LBR4P_Q0
    )
    n_single, n_ten, n_step = number, max(number // 10, 1), max(number // 8, 1)
    cols: dict[str, list[float]] = {k: [] for k in ("single", "ten", "classic")}
    ours: dict[str, list[float]] = {k: [] for k in ("single", "ten", "classic")}
    for _ in range(rounds):
        ours["single"].append(
            timeit.timeit(lambda: robot.fast.pose_and_jacobian(q), number=n_single) / n_single
        )
        cols["single"].append(timeit.timeit(peers["kin"], number=n_single) / n_single)
        ours["ten"].append(
            timeit.timeit(lambda: robot.fast.poses_and_jacobians(qs), number=n_ten) / n_ten
        )
        cols["ten"].append(timeit.timeit(peers["kin_ten"], number=n_ten) / n_ten)
        ours["classic"].append(float(np.median(loop(n_step))))
        cols["classic"].append(timeit.timeit(peers["classic"], number=n_step) / n_step)

    def ratio(key: str) -> float:
        return float(np.median(np.array(ours[key]) / np.array(cols[key])))

    def us(values: list[float]) -> float:
        return float(np.median(values) * 1e6)

    return {
        "version": peers["version"],
        "rounds": rounds,
        "fkm_pose_jacobian_us": us(cols["single"]),
        "ten_fkm_pose_jacobian_us": us(cols["ten"]),
        "classic_qp_step_us": us(cols["classic"]),
        "ours_single_us": us(ours["single"]),
        "ours_batch10_us": us(ours["ten"]),
        "ours_local_step_us": us(ours["classic"]),
        "ratios": {
            "single_kinematics_vs_dqr": ratio("single"),
            "batch10_vs_10x_dqr": ratio("ten"),
            "local_step_vs_dqr_classic_qp": ratio("classic"),
        },
    }


def bench_mujoco(duration_s: float = 2.0, period_s: float = PERIOD_S, repeats: int = 1) -> dict:
    """Wall time of the MuJoCo closed loop, predictive p = 10 (default backend) on the circle
    of ``duration_s``, ``T = period_s``: real-time factor = simulated / wall time."""
    from dqcontrol.sim.mujoco_loop import run_mujoco
    from dqcontrol.sim.mujoco_sim import MujocoSimulation

    robot = load_lbr4p()
    walls, sims, completed = [], [], True
    for _ in range(repeats):
        ctrl = _make("predictive", robot, Circle(duration_s), period_s, None, 10)
        sim = MujocoSimulation(robot)
        t0 = time.perf_counter()
        res = run_mujoco(ctrl, LBR4P_Q0, simulation=sim, max_time_s=2.0 * duration_s)
        walls.append(time.perf_counter() - t0)
        sims.append(len(res.log) * period_s)
        completed &= bool(ctrl.done)
    wall = float(np.median(walls))
    simulated = float(np.median(sims))
    return {
        "circle_s": duration_s,
        "period_s": period_s,
        "simulated_s": simulated,
        "wall_s": wall,
        "realtime_factor": simulated / wall,
        "completed": completed,
        "wall_runs_s": walls,
    }


def _targets(res: dict) -> dict:
    """Each target of :data:`TARGETS` with its figure and whether it is met."""
    ctl = res["controllers"]
    d = DEFAULT_SOLVER
    fig = {
        "local": ctl[f"local[{d}]"]["median_us"],
        "predictive_p6": ctl[f"predictive_p6[{d}]"]["median_us"],
        "predictive_p10": ctl[f"predictive_p10[{d}]"]["median_us"],
        "proportional": ctl["proportional"]["median_us"],
        "p99_over_median": max(
            ctl[k]["p99_over_median"]
            for k in (f"local[{d}]", f"predictive_p6[{d}]", f"predictive_p10[{d}]", "proportional")
        ),
    }
    four = (f"local[{d}]", f"predictive_p6[{d}]", f"predictive_p10[{d}]", "proportional")
    floor = [ctl[k].get("reference_p99_over_median") for k in four]
    ratios = res.get("ratios") or {}
    fig["local_vs_dqr_classic_qp"] = ratios.get("local_step_vs_dqr_classic_qp")
    fig["batch10_vs_10x_dqr"] = ratios.get("batch10_vs_10x_dqr")
    if res.get("mujoco"):
        fig["mujoco_realtime_factor"] = res["mujoco"]["realtime_factor"]
    pf = (res.get("path_following") or {}).get("by_p", {}).get(10)
    if pf:
        fig["path_following_p10"] = pf["median_us"]
        fig["path_following_p99"] = pf["p99_over_median"]
        fig["path_following_step_over_solve"] = pf["median_us"] / pf["levels_median_us"]
        pf_floor = pf.get("reference_p99_over_median"), pf.get("own_p99_over_median")
    if res.get("run_log"):
        fig["run_log_per_sample"] = res["run_log"]["median_us"]
    if res.get("collision"):
        fig["path_following_collision"] = res["collision"]["pf10"]["step_median_us"]
    out = {}
    for key, (label, op, bound, unit) in TARGETS.items():
        value = fig.get(key)
        met = None if value is None else (value <= bound if op == "<=" else value >= bound)
        out[key] = {"label": label, "value": value, "target": f"{op} {bound:g} {unit}", "met": met}
    if None not in floor:  # the host's own p99/median at the same durations (step_times)
        out["p99_over_median"]["host_floor"] = max(floor)
    own = [ctl[k].get("own_p99_over_median") for k in four]
    if None not in own:  # each step's fastest of the identical runs: the code's own variation
        out["p99_over_median"]["own_work"] = max(own)
    if pf and pf_floor[0] is not None:
        out["path_following_p99"]["host_floor"] = pf_floor[0]
    if pf and pf_floor[1] is not None:
        out["path_following_p99"]["own_work"] = pf_floor[1]
    return out


def bench_run_log(samples: int = 20_000, period_s: float = 0.001) -> dict:
    """Cost of recording one sample [µs]: the streamed log (:class:`~dqcontrol.runs.stream.
    StreamRecorder`, blocks of 1 s handed to its writer thread) against the in-memory
    :class:`~dqcontrol.runs.log.LogRecorder`, on a real step result of the LBR4p; each
    ``record`` call timed alone (the block hand-offs are in the p99 and max)."""
    import tempfile

    from dqcontrol.runs.log import LogRecorder
    from dqcontrol.runs.stream import StreamRecorder

    robot = load_lbr4p()
    controller = _make("local", robot, Circle(2.0), period_s, None)
    controller.reset(LBR4P_Q0)
    result = controller.step(LBR4P_Q0, np.zeros(robot.nq))
    q, qd = np.array(LBR4P_Q0, dtype=float), np.zeros(robot.nq)

    def timed(rec) -> np.ndarray:
        out = np.empty(samples)
        clock = time.perf_counter
        for k in range(samples):
            start = clock()
            rec.record(k * period_s, q, qd, result)
            out[k] = clock() - start
        return 1e6 * out

    with tempfile.TemporaryDirectory() as folder:
        rec = StreamRecorder(Path(folder) / "bench.mcap", robot.nq, period_s, {"bench": True})
        streamed = timed(rec)
        rec.close({"meta": rec.meta})
    memory = timed(LogRecorder(robot.nq))
    return {
        "samples": samples,
        "median_us": float(np.median(streamed)),
        "p99_us": float(np.percentile(streamed, 99)),
        "max_us": float(streamed.max()),
        "in_memory_median_us": float(np.median(memory)),
    }


def bench_streaming(seconds: float = 2.0, period_s: float = PERIOD_S) -> dict:
    """The path-following controller planned in its own process and streamed at 1 kHz on
    the wall clock (docs/theory.md §12): the plan period chosen from the measured step
    time (twice its p99, at least 5 ms, a whole number of periods), the streamer's and the
    planner's step times, late commands and lateness, and a sleeper's host stalls beside them."""
    from dqcontrol.streaming import streamed
    from dqcontrol.streaming.planner import choose_plan_period
    from dqcontrol.streaming.timing import time_on_wall_clock

    robot = load_lbr4p()
    probe = _make("path_following", robot, Circle(seconds), period_s, DEFAULT_SOLVER)
    probe.reset(LBR4P_Q0)
    q, times = LBR4P_Q0.copy(), []
    for _ in range(60):
        start = time.perf_counter()
        q = q + period_s * probe.step(q).qd_command
        times.append(time.perf_counter() - start)
    plan_period = choose_plan_period(times[10:], period_s)
    planner = _make("path_following", robot, Circle(seconds), plan_period, DEFAULT_SOLVER)
    controller = streamed(planner, period_s, acceleration_max=10.0, jerk_max=5000.0)
    timing = time_on_wall_clock(controller, LBR4P_Q0, seconds)
    report = controller.report()
    return {
        "plan_period_s": plan_period,
        "streamer_step_median_us": report["streamer_step_median_us"],
        "planner_step_median_ms": report["planner_step_median_ms"],
        "plans_used": report["plans_used"],
        "plans_refused": report["plans_refused"],
        **dataclasses.asdict(timing),
    }


def _streaming_lines(res: dict | None) -> list[str]:
    """The streamed controller on the wall clock."""
    if not res:
        return []
    return [
        "",
        f"streamed path following at 1 kHz (plan period {1e3 * res['plan_period_s']:g} ms, "
        f"planner in its own process): streamer step median "
        f"{res['streamer_step_median_us']:.1f} µs, planner step median "
        f"{res['planner_step_median_ms']:.2f} ms, plans used {res['plans_used']}, refused "
        f"{res['plans_refused']}",
        f"  wall clock: {res['late']} of {res['samples']} commands late "
        f"({res['late_during_host_stalls']} during host stalls ≥ 2.5 ms), lateness median "
        f"{res['lateness_median_ms']:.3f} ms, p99 {res['lateness_p99_ms']:.2f} ms, max "
        f"{res['lateness_max_ms']:.2f} ms; sleeper's host stalls: {res['host_stalls']}, p99 "
        f"{res['host_stall_p99_ms']:.2f} ms, max {res['host_stall_max_ms']:.2f} ms",
    ]


def _run_log_lines(res: dict | None) -> list[str]:
    """The streamed run log's cost per sample and its size on disk."""
    if not res:
        return []
    return [
        "",
        f"streamed run log ({res['samples']} samples at 1 kHz): record median "
        f"{res['median_us']:.2f} µs, p99 {res['p99_us']:.2f} µs, max {res['max_us']:.0f} µs "
        f"(block hand-offs and host noise); in memory {res['in_memory_median_us']:.2f} µs",
    ]


def run_all(quick: bool = False) -> dict:
    """Every figure of the benchmark, with peer ratios, targets and the machine.

    ``quick`` (seconds, for tests and CI) runs few steps, a short MuJoCo run and a reduced
    scaling sweep: its figures are indicative only.
    """
    if quick:
        steps, repeats, kin_n = 150, 2, 200
    else:
        steps, repeats, kin_n = 2000, 5, 2000
    out: dict = {
        "machine": machine(),
        "quick": quick,
        "period_s": PERIOD_S,
        "default_solver": DEFAULT_SOLVER,
        "kinematics": bench_kinematics(number=kin_n, repeat=5 if quick else 9),
        "controllers": bench_controllers(
            steps=steps, repeats=repeats, other_repeats=max(1, repeats - 2)
        ),
        "agreement": bench_agreement(steps=100 if quick else 2000),
    }
    peers = bench_dqrobotics(number=kin_n, rounds=3 if quick else 15)
    if peers:
        out["ratios"] = peers.pop("ratios")
    out["dqrobotics"] = peers
    out["mujoco"] = bench_mujoco(duration_s=0.5 if quick else 2.0, repeats=1 if quick else 3)
    if quick:
        out["scaling"] = bench_scaling(steps=60, repeats=1, ps=(2, 10), joints=(7, 14))
        out["path_following"] = bench_path_following(steps=20, repeats=2, ps=(6, 10), joints=(7,))
        out["collision"] = bench_collision(steps=20)
        out["collision"]["pf10_whole_circle"] = bench_collision_circle(max_factor=0.01)
    else:
        out["scaling"] = bench_scaling()
        out["path_following"] = bench_path_following()
        out["collision"] = bench_collision()
        out["collision"]["pf10_whole_circle"] = bench_collision_circle()
    out["run_log"] = bench_run_log(samples=3000 if quick else 20_000)
    out["streaming"] = bench_streaming(seconds=0.5 if quick else 2.0)
    out["targets"] = _targets(out)
    return out


def _fmt(value, unit: str) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "—"
    return f"{value:.3g} {unit}" if unit == "×" else f"{value:.0f} {unit}"


def format_report(res: dict) -> str:
    """Human-readable report of :func:`run_all`'s figures."""
    lines = _header_lines(res) + _target_lines(res["targets"])
    lines += _controller_lines(res) + _agreement_lines(res["agreement"])
    lines += _kinematics_lines(res) + _mujoco_lines(res["mujoco"])
    lines += _scaling_lines(res["scaling"])
    lines += _path_following_lines(res.get("path_following"))
    lines += _collision_lines(res.get("collision"))
    lines += _run_log_lines(res.get("run_log"))
    lines += _streaming_lines(res.get("streaming"))
    return "\n".join(lines)


def _header_lines(res: dict) -> list[str]:
    """The machine and the packages."""
    m = res["machine"]
    pk = ", ".join(f"{k} {v}" for k, v in m["packages"].items() if v)
    lines = [
        f"machine: {m['cpu']}, {m['cores']} cores, Python {m['python']} ({m['platform']})",
        f"packages: {pk}",
    ]
    if res.get("quick"):
        lines.append("QUICK MODE: few steps, indicative figures only")
    return lines


def _target_lines(targets: dict) -> list[str]:
    """Each target, its figure and whether it is met, with the host's floor and the
    code's own variation where measured."""
    lines = ["", "targets"]
    for t in targets.values():
        unit = t["target"].split()[-1]
        state = {True: "met", False: "NOT MET", None: "not measured"}[t["met"]]
        lines.append(
            f"  {t['label']:48s} {_fmt(t['value'], unit):>10s}  {t['target']:>10s}  {state}"
        )
        if "host_floor" in t:
            lines.append(
                f"    (a constant workload as long as the median step, on this host: "
                f"{t['host_floor']:.2f} ×)"
            )
        if "own_work" in t:
            lines.append(
                f"    (each step's fastest of the identical runs, the code's own variation: "
                f"{t['own_work']:.2f} ×)"
            )
    return lines


def _controller_lines(res: dict) -> list[str]:
    """The step-time table of the controllers on both backends."""
    period_ms = res["period_s"] * 1e3
    lines = [
        "",
        f"control step, LBR4p, circle T_tot = 2 s, T = {period_ms:g} ms (default backend: "
        f"{res['default_solver']})",
        f"  {'controller[backend]':28s} {'median':>8s} {'p99':>8s} {'p99/med':>8s} "
        f"{'solver':>8s} {'iters':>6s} {'host':>6s} {'own':>6s}  [µs]",
    ]
    for k, v in res["controllers"].items():
        host = v.get("reference_p99_over_median")
        own = v.get("own_p99_over_median")
        lines.append(
            f"  {k:28s} {v['median_us']:8.1f} {v['p99_us']:8.1f} {v['p99_over_median']:8.2f} "
            f"{v['solver_median_us']:8.1f} {v['iterations_median']:6.0f} "
            f"{'—' if host is None else f'{host:.2f}':>6s} "
            f"{'—' if own is None else f'{own:.2f}':>6s}"
        )
    lines.append(
        "  host: p99/median of a constant workload of the step's median, run after every step"
    )
    lines.append(
        "  own: p99/median of each step's fastest time over the identical runs (same work)"
    )
    return lines


def _agreement_lines(agreement: dict) -> list[str]:
    """The largest differences between the DAQP and the OSQP backend."""
    lines = ["", "backends agree (max over a run, DAQP vs OSQP + refinement)"]
    for k, v in agreement.items():
        lines.append(
            f"  {k:16s} |Δqd| {v['max_abs_qd_diff']:.1e} rad/s   |Δs| {v['max_abs_s_diff']:.1e}"
        )
    return lines


def _kinematics_lines(res: dict) -> list[str]:
    """The kinematics' times and the ratios against DQ Robotics, where installed."""
    kin = res["kinematics"]
    lines = ["", "kinematics (pose + pose Jacobian, LBR4p) [µs, median]"]
    lines.append(f"  ours single {kin['single_us']:.1f}, batch of 10 {kin['batch10_us']:.1f}")
    peers = res.get("dqrobotics")
    if not peers:
        return lines + ["  DQ Robotics not installed: no peer ratios (pip install dqrobotics)"]
    lines.append(
        f"  DQ Robotics {peers['version']}: "
        f"fkm + pose_jacobian {peers['fkm_pose_jacobian_us']:.1f}, "
        f"ten of them {peers['ten_fkm_pose_jacobian_us']:.1f}; "
        f"DQ_ClassicQPController step {peers['classic_qp_step_us']:.1f}"
    )
    r = res["ratios"]
    lines.append(
        f"  ours in the same rounds: single {peers['ours_single_us']:.1f}, batch of 10 "
        f"{peers['ours_batch10_us']:.1f}, local step {peers['ours_local_step_us']:.1f}"
    )
    lines.append(
        f"  ratios (median of {peers['rounds']} interleaved rounds): single kinematics "
        f"{r['single_kinematics_vs_dqr']:.2f}×, batch of 10 vs ten DQR calls "
        f"{r['batch10_vs_10x_dqr']:.2f}×, local step vs ClassicQP step "
        f"{r['local_step_vs_dqr_classic_qp']:.2f}×"
    )
    return lines


def _mujoco_lines(mj: dict) -> list[str]:
    """The MuJoCo closed loop's real-time factor."""
    return [
        "",
        f"MuJoCo closed loop, predictive p = 10, T = {mj['period_s'] * 1e3:g} ms, "
        f"{mj['circle_s']:g} s circle: {mj['simulated_s']:.2f} s simulated in "
        f"{mj['wall_s']:.2f} s wall (real-time factor {mj['realtime_factor']:.2f}"
        f"{'' if mj['completed'] else ', circle NOT completed'})",
    ]


def _scaling_lines(sc: dict) -> list[str]:
    """The predictive step against p and against the joint count, with the fitted
    exponents."""
    lines = ["", f"predictive step against p (LBR4p, {sc['solver']}) [µs]: median (solver)"]
    lines.append(
        "  "
        + ", ".join(
            f"p={p}: {v['median_us']:.0f} ({v['solver_median_us']:.0f})"
            for p, v in sc["by_p"].items()
        )
    )
    lines.append(
        f"  fit t ∝ p^k: step k = {sc['fit_p']['median_us']:.2f}, "
        f"solver k = {sc['fit_p']['solver_median_us']:.2f}"
    )
    lines.append("predictive p = 10 against the number of joints [µs]: median (solver)")
    lines.append(
        "  "
        + ", ".join(
            f"n={n}: {v['median_us']:.0f} ({v['solver_median_us']:.0f})"
            for n, v in sc["by_joints_p10"].items()
        )
    )
    lines.append(
        f"  fit t ∝ n^k: step k = {sc['fit_joints']['median_us']:.2f}, "
        f"solver k = {sc['fit_joints']['solver_median_us']:.2f}"
    )
    return lines


def _collision_lines(col: dict | None) -> list[str]:
    """The collision section of the report."""
    if not col:
        return []
    lines = [
        "",
        f"collision limit (three obstacles + self-collision, {col['pairs']} pairs) [µs]: "
        "step median (and without the limit), the limit's rows() median, rows, pairs "
        "within the influence distance, distance queries (coal) and closed-form distances "
        "per step",
    ]
    for name in ("local", "pf10"):
        v = col[name]
        lines.append(
            f"  {name}: step {v['step_median_us']:.0f} (without the limit "
            f"{v['step_without_limit_median_us']:.0f}), limit rows {v['limit_median_us']:.0f}, "
            f"{v['rows_mean']:.1f} rows, {v['pairs_in_influence_mean']:.1f} pairs, "
            f"{v['distance_queries_mean']:.1f} queries, "
            f"{v['closed_form_distances_mean']:.1f} closed forms"
        )
    whole = col.get("pf10_whole_circle")
    if whole:  # the quick run stops after its first steps
        lines.append(
            f"  pf10 over the whole circle: {whole['steps']} steps "
            f"({'completed' if whole['completed'] else 'NOT completed'}), median "
            f"{whole['step_median_us']:.0f}, p99 {whole['step_p99_us']:.0f}, "
            f"{100 * whole['over_period_share']:.1f} % of the steps over the period, "
            f"{whole['fallbacks']} fallbacks, closest "
            + ("—" if whole["closest_mm"] is None else f"{whole['closest_mm']:.2f} mm")
        )
    return lines


def _path_following_lines(pf: dict | None) -> list[str]:
    """The path-following section of the report."""
    if not pf:
        return []
    lines = [
        "",
        "path-following step (LBR4p, circle 2 s) [µs]: median / p99 (prioritised solve; "
        "solver calls alone), rounds",
    ]
    for p, v in pf["by_p"].items():
        lines.append(
            f"  p={p}: {v['median_us']:.0f} / {v['p99_us']:.0f} ({v['levels_median_us']:.0f}; "
            f"{v['solver_median_us']:.0f}), step/solve {v['median_us'] / v['levels_median_us']:.2f}"
            f" ({v['median_us'] / v['solver_median_us']:.2f} over the solver calls), "
            f"{v['linearisations_mean']:.2f} rounds (max {v['linearisations_max']}), "
            f"{v['iterations_median']:.0f} solver iterations"
        )
        if "reference_p99_over_median" in v:
            own = v.get("own_p99_over_median")
            lines.append(
                f"    p99/median {v['p99_over_median']:.2f} (host floor "
                f"{v['reference_p99_over_median']:.2f}"
                + (f", the code's own {own:.2f})" if own is not None else ")")
            )
        if "held_over_unheld" in v:
            lines.append(
                f"    one BLAS thread held over the loop / each step switching it itself: "
                f"{v['held_over_unheld']:.3f} (interleaved)"
            )
    dyn = pf.get("dynamics_p10")
    if dyn:
        lines.append(
            f"  p=10 with its default dynamics-aware acceleration bound: {dyn['median_us']:.0f} / "
            f"{dyn['p99_us']:.0f} ({dyn['levels_median_us']:.0f}), step/solve "
            f"{dyn['median_us'] / dyn['levels_median_us']:.2f}"
        )
    lines.append("path-following p = 10 against the number of joints [µs]: median (solver)")
    lines.append(
        "  "
        + ", ".join(
            f"n={n}: {v['median_us']:.0f} ({v['solver_median_us']:.0f})"
            for n, v in pf["by_joints_p10"].items()
        )
    )
    return lines


def main(out: str | os.PathLike | None = "results/bench.json", quick: bool = False) -> dict:
    """Run, print and (atomically) write ``results/bench.json``."""
    from dqcontrol.runs import atomic_write_text

    res = run_all(quick=quick)
    print(format_report(res))
    if out:
        path = atomic_write_text(Path(out), json.dumps(res, indent=2, default=str) + "\n")
        print(f"\nwritten: {path}")
    return res


if __name__ == "__main__":
    import argparse

    parser = argparse.ArgumentParser(description="Every step-time figure (as dqcontrol bench).")
    parser.add_argument("--out", default="results/bench.json", help="JSON output file")
    parser.add_argument("--quick", action="store_true", help="few steps (indicative only)")
    args = parser.parse_args()
    main(out=args.out, quick=args.quick)
