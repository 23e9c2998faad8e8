"""One case of the ``arms`` experiment: an arm, a task, a loop, a period and a controller
with its defaults, run and measured (docs/arms.md).

Beyond the run's metrics (docs/theory.md §9) a case measures what names a missed goal: the
largest path deviation between the samples, the peak joint torque against the URDF's effort
limits (MuJoCo), the execution time against the TOPP-RA bound of the same joint path (the
URDF's velocity limits, the dynamics-aware acceleration bound and the effort limits), and
the robot's contacts in MuJoCo at the logged samples (pairs of bodies and the deepest
penetration).
"""

from __future__ import annotations

import math
import threading
import time
from dataclasses import asdict, dataclass

import numpy as np

from dqcontrol.studies.arms_spec import ArmSpec, ArmsSettings
from dqcontrol.studies.spec import Study

__all__ = ["ArmsCase", "load_arm", "run_arms_case"]

_LOCAL = threading.local()


@dataclass(frozen=True, order=True)
class ArmsCase:
    """One cell of the grid (the order is the table's)."""

    arm: str
    task: str
    simulator: str
    period_s: float
    controller: str
    duration_s: float

    @property
    def name(self) -> str:
        """File-name friendly label, e.g. ``ur5_circle_kinematic_T10ms_pf``."""
        return (
            f"{self.arm}_{self.task}_{self.simulator}_T{1e3 * self.period_s:g}ms_{self.controller}"
        )


def load_arm(arm: ArmSpec, start: str):
    """The arm's robot model (once per thread) and its start ``q0`` [rad] of kind ``start``."""
    from dqcontrol.cli.robot_options import RobotRequest, load_robot

    cache = getattr(_LOCAL, "arms", None)
    if cache is None:
        cache = _LOCAL.arms = {}
    if arm.name not in cache:
        request = RobotRequest(arm.robot, arm.ee_frame, arm.locked)
        try:
            cache[arm.name] = load_robot(request)[:2]
        except ValueError as exc:
            from dqcontrol.errors import ParameterError

            raise ParameterError(f"arm {arm.name!r}: {exc}") from None
    robot, shipped_q0 = cache[arm.name]
    q0 = arm.start(start)
    return robot, (shipped_q0.copy() if q0 is None else robot.check_q(np.array(q0), "q0"))


def velocity_limits(arm: ArmSpec, robot) -> np.ndarray:
    """What ``dqcontrol run`` uses: the thesis's limits on the LBR4p, else the URDF's."""
    from dqcontrol.experiments.thesis import THESIS_VELOCITY_LIMITS

    if arm.robot == "lbr4p" and robot.nq == len(THESIS_VELOCITY_LIMITS):
        return np.array(THESIS_VELOCITY_LIMITS, dtype=float)
    return np.array(robot.limits.qd_max, dtype=float)


def _bound_s(
    robot, trajectory, q0: np.ndarray, v_max: np.ndarray, end_at_rest: bool
) -> tuple[float, str]:
    """The TOPP-RA bound [s] of the task's joint path, or NaN and why it has none: from
    rest to rest for a controller that ends the task at rest, else with a free end."""
    from dqcontrol.errors import DQControlError
    from dqcontrol.experiments.time_optimal import time_optimal_bound

    key = (id(robot), trajectory.to_metadata().__repr__(), q0.tobytes(), end_at_rest)
    cache = getattr(_LOCAL, "bounds", None)
    if cache is None:
        cache = _LOCAL.bounds = {}
    if key not in cache:
        try:
            bound = time_optimal_bound(
                robot, trajectory, q0, velocity_limits=v_max,
                acceleration_limit="dynamics", torque_limits="urdf", end_at_rest=end_at_rest,
            )  # fmt: skip
            cache[key] = (bound.duration_s, "")
        except (DQControlError, ValueError, RuntimeError) as exc:  # toppra's own failures too
            cache[key] = (math.nan, f"no TOPP-RA bound: {exc}")
    return cache[key]


def _torque_ratio(robot, log) -> tuple[float, int]:
    """The largest ``|τ| / τ_max`` over the run's periods and its joint (NaN, -1 without
    torques)."""
    peak = np.asarray(log.torque_peak, dtype=float)
    effort = np.asarray(robot.limits.effort_max, dtype=float)
    if peak.size == 0 or not np.isfinite(peak).any():
        return math.nan, -1
    ratio = np.nanmax(np.abs(peak), axis=0) / np.where(np.isfinite(effort), effort, np.inf)
    joint = int(np.nanargmax(ratio))
    return float(ratio[joint]), joint


def _contacts(robot, q_samples: np.ndarray) -> dict:
    """The robot's contacts in MuJoCo at the samples: count of samples in contact, the
    deepest penetration [m] and the pairs of bodies."""
    import mujoco

    from dqcontrol.sim.mujoco_sim import MujocoSimulation

    sim = MujocoSimulation(robot)
    model, data = sim.model, sim.data
    pairs: set[str] = set()
    touching, deepest = 0, 0.0
    for q in q_samples:
        sim.reset(q)
        mujoco.mj_forward(model, data)
        if data.ncon:
            touching += 1
        for c in data.contact[: data.ncon]:
            names = sorted(
                mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, model.geom_bodyid[g]) or "world"
                for g in (c.geom1, c.geom2)
            )
            pairs.add("–".join(names))
            deepest = max(deepest, -float(c.dist))
    return {"samples": touching, "deepest_m": deepest, "pairs": sorted(pairs)}


def _smallest_singular_value(robot, q_samples: np.ndarray) -> float:
    """The smallest singular value of the tangent Jacobian ``E J`` over the samples
    (docs/theory.md §8.3): how close the run came to a singular configuration."""
    from dqcontrol.controllers.terms.path_error import tangent_projectors

    if len(q_samples) == 0:
        return math.nan
    poses, jacobians = robot.poses_and_jacobians(np.asarray(q_samples))
    tangent = np.einsum("kij,kjl->kil", tangent_projectors(poses), jacobians)
    return float(np.min(np.linalg.svd(tangent, compute_uv=False)[:, -1]))


def run_arms_case(case: ArmsCase, study: Study, save_dir: str | None = None) -> dict:
    """Run one case and return plain data: the case, the run's metrics, the measurements of
    the module's text, the wall time and the saved files."""
    from dqcontrol.experiments.runner import build_trajectory, simulate
    from dqcontrol.registry import build_controller
    from dqcontrol.runs.storage import save_run
    from dqcontrol.sim.mujoco_sim import SERVO_TIME_CONSTANT_S

    start = time.perf_counter()
    settings: ArmsSettings = study.settings
    arm, task = settings.arm(case.arm), settings.task(case.task)
    robot, q0 = load_arm(arm, task.start)
    trajectory = build_trajectory(study.trajectory(task.trajectory).metadata(case.duration_s))
    v_max = velocity_limits(arm, robot)
    shared: dict = {"velocity_limits": v_max}
    if case.simulator == "mujoco":  # as `dqcontrol run`: the servos' lag to who models it
        shared["servo_time_constant_s"] = SERVO_TIME_CONSTANT_S
    controller = build_controller(case.controller, robot, trajectory, case.period_s, shared=shared)
    meta = {"study": study.name, "case": case.name}
    run = simulate(
        controller, q0, case.simulator, between_samples=True,
        max_time_s=settings.max_time_factor * case.duration_s, meta=meta,
    )  # fmt: skip
    result = run.result
    ratio, joint = _torque_ratio(robot, result.log)
    bound_s, bound_note = _bound_s(robot, trajectory, q0, v_max, controller.ends_at_rest)
    samples = result.log.q[: max(result.metrics.samples, 1)]
    contacts = _contacts(robot, samples) if case.simulator == "mujoco" else None
    sigma_min = _smallest_singular_value(robot, samples)
    files = None if save_dir is None else [str(p) for p in save_run(result, save_dir, case.name)]
    return {
        "case": asdict(case),
        "metrics": result.metrics.as_dict(),
        "between_deviation_max_m": run.between_deviation_max_m,
        "torque_ratio": ratio,
        "torque_joint": joint,
        "bound_s": bound_s,
        "bound_note": bound_note,
        "contacts": contacts,
        "sigma_min": sigma_min,
        "interrupted": bool(result.interrupted),
        "note": result.note,
        "wall_time_s": time.perf_counter() - start,
        "files": files,
    }
