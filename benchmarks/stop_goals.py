"""The rest-to-rest and path-maintaining-stop goals, measured (docs/theory.md §8.9–8.10).

The Franka Panda with the ``franka_panda`` limit profile (velocity, acceleration and jerk)
given to the path-following controller, on a circle of radius ``--radius`` [m] (or, ``--path
waypoints``, the user guide's four waypoints) lasting ``--duration`` [s], at
``T = --period`` [s], in the kinematic loop (and MuJoCo with ``--mujoco``):

* rest to rest: the run to the end of the task and its stop; the largest path deviation
  (task and stop), the last command, the tool's distance from the path's end;
* a stop requested at ``σ = T_tot/2``: its duration against the fastest stop along the
  same path under the same velocity and acceleration limits, computed offline with TOPP-RA
  (zero end velocity) on the joint path that leaves the stop's start state with no
  self-motion, the fastest over stopping lengths up to 0.4 s of phase;
* the checker (:func:`~dqcontrol.runs.check.check_run`, the profile) on every run, its
  summary printed;
* the jerk bound's cost: the rest-to-rest execution time with the profile's jerk against
  the same run without a jerk bound (kinematic loop).

Prints one line per figure; ``--json FILE`` writes them. Not a unit test (it takes a few
minutes at 1 kHz).
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np

import dqcontrol
from dqcontrol.controllers.path_following.controller import PathFollowingController
from dqcontrol.dq import qfrom_axis_angle
from dqcontrol.dq.algebra import translation
from dqcontrol.model import PANDA_Q0
from dqcontrol.runs.check import check_run, summary_line
from dqcontrol.sim import KinematicDriver, MujocoDriver, run_loop
from dqcontrol.trajectories import Circle, WaypointTrajectory

#: Franka's published limits (libfranka's rate limiter) [rad/s], [rad/s²].
FRANKA_VELOCITY = np.array([2.175, 2.175, 2.175, 2.175, 2.61, 2.61, 2.61])
FRANKA_ACCELERATION = np.array([15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0])


def _task(args):
    """The circle, or four waypoints with the tool turning about its z-axis."""
    if args.path == "circle":
        return Circle(args.duration, radius_m=args.radius)
    z = np.array([0.0, 0.0, 1.0])
    return WaypointTrajectory(
        positions_m=[[0.0, 0.0, 0.0], [0.08, 0.05, 0.0], [0.12, -0.05, 0.03], [0.0, 0.0, 0.0]],
        orientations=[qfrom_axis_angle(z, np.radians(a)) for a in (0.0, 30.0, -20.0, 0.0)],
        duration_s=args.duration,
    )


def _controller(robot, args, end: str = "rest") -> PathFollowingController:
    return PathFollowingController(
        robot, _task(args), args.period,
        velocity_limits=FRANKA_VELOCITY, acceleration_limit=FRANKA_ACCELERATION, end=end,
    )  # fmt: skip


def _checked(result, robot, args, name: str) -> int:
    """The checker's violations of the run against the profile (its summary printed)."""
    found = check_run(result.log, robot.limits, period_s=args.period)
    print(summary_line(found, len(result.log), args.period, "franka_panda", name))
    return len(found)


def _driver(robot, args, mujoco: bool):
    return MujocoDriver(robot, args.period) if mujoco else KinematicDriver(robot, args.period)


def _figures(result, controller, prefix: str) -> dict:
    """The run's figures: deviations, the last command, the end's distance, the stop."""
    log, m = result.log, result.metrics
    traj = controller.trajectory
    dev = traj.path_deviation(translation(log.pose))
    end_point = translation(traj.target(traj.duration)[None])[0]
    tool_end = translation(log.pose[-1:])[0]
    return {
        f"{prefix}_reason": result.log.meta["stop"]["reason"],
        f"{prefix}_path_deviation_max_mm": 1e3 * float(np.max(dev)),
        f"{prefix}_stop_path_deviation_max_mm": 1e3 * m.stop_path_deviation_max_m,
        f"{prefix}_last_command_rad_s": float(np.max(np.abs(log.qd_command[-1]))),
        f"{prefix}_end_distance_mm": 1e3 * float(np.linalg.norm(tool_end - end_point)),
        f"{prefix}_stop_duration_s": m.stop_duration_s,
        f"{prefix}_stop_samples": m.stop_samples,
        f"{prefix}_stop_limit_violations": m.stop_limit_violations,
        f"{prefix}_acceleration_violations": m.acceleration_violations,
        f"{prefix}_ramp": result.log.meta["stop"].get("ramp", ""),
    }  # fmt: skip


def _stop_at_half(robot, args, mujoco: bool):
    controller = _controller(robot, args)
    half = 0.5 * args.duration

    def on_sample(k, driver, result) -> None:
        if result.sigma_next >= half and not controller.stopping:
            controller.request_stop()

    result = run_loop(controller, _driver(robot, args, mujoco), q0=PANDA_Q0, on_sample=on_sample)
    return result, controller


def _least_norm_path(robot, trajectory, q0, sigma0: float, length: float, step: float = 5e-4):
    """``(σ, q)`` from ``(σ0, q0)`` over ``length`` of phase along the path with no motion in
    its null space: ``dq/dσ = J⁺(q) x_d'(σ)`` (least norm), integrated with RK4. The joint
    path a stop without self-motion follows."""

    def slope(sigma: float, q: np.ndarray) -> np.ndarray:
        jac = robot.pose_jacobian(q)
        return np.linalg.lstsq(jac, trajectory.target_derivative(sigma), rcond=None)[0]

    steps = int(np.ceil(length / step))
    sigma = sigma0 + step * np.arange(steps + 1)
    q = np.empty((steps + 1, q0.size))
    q[0] = q0
    for k in range(steps):
        x, h = q[k], step
        k1 = slope(sigma[k], x)
        k2 = slope(sigma[k] + h / 2, x + h / 2 * k1)
        k3 = slope(sigma[k] + h / 2, x + h / 2 * k2)
        k4 = slope(sigma[k] + h, x + h * k3)
        q[k + 1] = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return sigma, q


def _toppra_stop(sigma, q, sigma0: float, s0: float, length: float) -> float | None:
    """TOPP-RA's fastest time from ``(σ0, σ̇ = s0)`` to rest at ``σ0 + length``, or ``None``."""
    import toppra
    import toppra.constraint as tc
    from scipy.interpolate import CubicSpline

    knots = np.linspace(0.0, length, 80)
    path = toppra.SplineInterpolator(knots, CubicSpline(sigma, q)(sigma0 + knots))
    grid = np.linspace(0.0, length, 400)
    constraints = [
        tc.JointVelocityConstraint(np.column_stack((-FRANKA_VELOCITY, FRANKA_VELOCITY))),
        tc.JointAccelerationConstraint(
            np.column_stack((-FRANKA_ACCELERATION, FRANKA_ACCELERATION)),
            discretization_scheme=tc.DiscretizationType.Interpolation,
        ),
    ]
    algorithm = toppra.algorithm.TOPPRA(constraints, path, gridpoints=grid)
    trajectory = algorithm.compute_trajectory(s0, 0.0)
    return None if trajectory is None else float(trajectory.duration)


def _fastest_stop(sigma, q, sigma0: float, s0: float, max_length: float = 0.4):
    """``(time, length)`` of the fastest stop along the joint path from ``(σ0, s0)``, over
    stopping lengths from 0.002 to ``max_length`` of phase (a scan: where the path slows
    down further on, a longer stop may be infeasible while a shorter one is not), or
    ``(nan, nan)``. ``s0`` is at most the speed the velocity limits allow there on the
    spline, which may differ from the controller's joint motion by rounding."""
    from scipy.interpolate import CubicSpline

    slope = np.abs(CubicSpline(sigma, q)(sigma0, 1))
    s0 = min(s0, float(np.min(FRANKA_VELOCITY / np.maximum(slope, 1e-12))) * (1 - 1e-9))
    times = [(t, length) for length in np.geomspace(0.002, max_length, 60)
             if (t := _toppra_stop(sigma, q, sigma0, s0, length)) is not None]  # fmt: skip
    return min(times) if times else (float("nan"), float("nan"))


def _execution(robot, args) -> float:
    """The rest-to-rest execution time [s] (kinematic, no stop) on ``robot`` (with the
    profile: its jerk bound; the URDF's limits: none; Franka's velocity and acceleration
    either way)."""
    run = run_loop(_controller(robot, args), KinematicDriver(robot, args.period), q0=PANDA_Q0,
                   brake=False)  # fmt: skip
    return run.metrics.execution_time_s


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--period", type=float, default=0.001)
    ap.add_argument("--duration", type=float, default=1.0)
    ap.add_argument("--radius", type=float, default=0.15)
    ap.add_argument("--path", choices=("circle", "waypoints"), default="circle")
    ap.add_argument("--mujoco", action="store_true", help="also in MuJoCo")
    ap.add_argument("--json", help="write the figures here")
    args = ap.parse_args(argv)
    robot = dqcontrol.load_panda().with_limits("franka_panda")
    figures: dict = {}
    for mujoco in (False, True) if args.mujoco else (False,):
        tag = "mujoco" if mujoco else "kinematic"
        controller = _controller(robot, args)
        start = time.perf_counter()
        end_run = run_loop(controller, _driver(robot, args, mujoco), q0=PANDA_Q0)
        figures.update(_figures(end_run, controller, f"{tag}_rest"))
        figures[f"{tag}_rest_check_violations"] = _checked(end_run, robot, args, f"{tag}_rest")
        stop_run, controller = _stop_at_half(robot, args, mujoco)
        figures.update(_figures(stop_run, controller, f"{tag}_stop_half"))
        figures[f"{tag}_stop_half_check_violations"] = _checked(
            stop_run, robot, args, f"{tag}_stop_half"
        )
        task = np.flatnonzero(~stop_run.log.stopping)[-1]
        figures[f"{tag}_stop_sigma0_s"] = float(
            stop_run.log.sigma[task] + args.period * stop_run.log.s[task]
        )
        figures[f"{tag}_stop_s0"] = float(stop_run.log.s[task])
        if not mujoco:
            stop_controller, stop_q0 = controller, stop_run.log.q[task + 1]
        figures[f"{tag}_wall_s"] = time.perf_counter() - start
    with_jerk, without = _execution(robot, args), _execution(dqcontrol.load_panda(), args)
    figures["kinematic_rest_execution_s"] = with_jerk
    figures["kinematic_no_jerk_execution_s"] = without
    figures["jerk_cost_ratio"] = with_jerk / without
    sigma0 = figures["kinematic_stop_sigma0_s"]
    length = min(0.4, stop_controller.trajectory.duration - sigma0)
    sigma, q = _least_norm_path(robot, stop_controller.trajectory, stop_q0, sigma0, length)
    best, length = _fastest_stop(sigma, q, sigma0, figures["kinematic_stop_s0"], length)
    figures["toppra_fastest_stop_s"] = best
    figures["toppra_fastest_stop_length_s"] = length
    figures["kinematic_stop_ratio_to_toppra"] = (
        figures["kinematic_stop_half_stop_duration_s"] / best
    )
    for key, value in figures.items():
        print(f"{key}: {value:.6g}" if isinstance(value, float) else f"{key}: {value}")
    if args.json:
        with open(args.json, "w", encoding="utf-8") as out:
            json.dump(figures, out, indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main())
