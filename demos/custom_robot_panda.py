"""Your own robot from its URDF: the Franka Panda of example-robot-data, loaded with
``RobotModel.from_urdf``, follows a waypoint path whose orientation changes along the way
(predictive controller, p = 10, in MuJoCo built from the same URDF).

    python demos/custom_robot_panda.py            # results/demos/panda/
    python demos/custom_robot_panda.py --viewer   # watch it live in the browser
    python demos/custom_robot_panda.py --short    # quick headless run (what CI executes)
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from dqcontrol import RobotModel
from dqcontrol.controllers import PredictiveController
from dqcontrol.dq import qfrom_axis_angle
from dqcontrol.model import PANDA_Q0, panda_urdf_path
from dqcontrol.sim import run_mujoco
from dqcontrol.trajectories import WaypointTrajectory
from dqcontrol.viz.figures import plot_run
from dqcontrol.viz.meshcat_viewer import MeshcatViewer, export_replay_html


def load_robot() -> RobotModel:
    """Any URDF works the same way: the file, the end-effector frame, the joints to hold
    fixed, and where ``package://`` meshes live (for the viewer and MuJoCo)."""
    urdf_path, package_dir = panda_urdf_path()  # .../panda_description/urdf/panda.urdf
    return RobotModel.from_urdf(
        urdf_path,
        "panda_hand_tcp",
        locked_joints={"panda_finger_joint1": 0.0, "panda_finger_joint2": 0.0},
        package_dirs=[package_dir],
    )


def make_trajectory(duration_s: float) -> WaypointTrajectory:
    """Five waypoints in the start tool frame (z along the gripper), the tool turning about
    its approach axis and tilting on the way, back to the start."""
    positions_m = [
        [0.00, 0.00, 0.00],
        [0.10, 0.06, 0.00],
        [0.14, -0.06, 0.04],
        [0.02, -0.10, 0.02],
        [0.00, 0.00, 0.00],
    ]
    z, x = np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0])
    orientations = [
        qfrom_axis_angle(z, 0.0),
        qfrom_axis_angle(z, np.radians(35.0)),
        qfrom_axis_angle(x, np.radians(15.0)),
        qfrom_axis_angle(z, np.radians(-30.0)),
        qfrom_axis_angle(z, 0.0),
    ]
    return WaypointTrajectory(positions_m, orientations, duration_s=duration_s)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--short", action="store_true", help="quick headless run (for CI)")
    parser.add_argument("--viewer", action="store_true", help="show the robot in the browser")
    parser.add_argument("--duration", type=float, default=4.0, help="T_tot [s] (default 4)")
    parser.add_argument("--out", default="results/demos/panda", help="output folder")
    args = parser.parse_args(argv)

    robot = load_robot()
    print(f"{robot.nq} joints {robot.joint_names}, end effector {robot.ee_frame}")
    trajectory = make_trajectory(args.duration)
    # velocity bounds: the URDF's (the default); acceleration bound 10 rad/s²
    controller = PredictiveController(
        robot, trajectory, period_s=0.05, num_instants=10, acceleration_limit=10.0
    )

    viewer = MeshcatViewer(robot, q=PANDA_Q0) if args.viewer else None
    result = run_mujoco(
        controller, PANDA_Q0, on_sample=viewer.follow(controller) if viewer else None
    )
    m = result.metrics
    print(
        f"Panda, waypoints, T_tot = {args.duration:g} s, p = 10, MuJoCo: completed="
        f"{m.completed}, execution time {m.execution_time_s:.3f} s, max translation error "
        f"{1e3 * m.translation_error_max_m:.2f} mm, max rotation error "
        f"{np.degrees(m.rotation_error_max_rad):.2f} deg, peak torque {m.torque_peak_nm:.1f} N·m"
    )

    out = Path(args.out)
    paths = plot_run(
        result.log,
        out,
        name="panda_p10",
        trajectory=controller.trajectory,
        figures=("path_3d", "rotation") if args.short else None,
        dpi=60 if args.short else 110,
    )
    if not args.short:  # the Panda's meshes make a 15 MB page
        paths.append(
            export_replay_html(
                robot,
                result.log,
                out / "panda_p10_replay.html",
                path_points=controller.trajectory.path_positions(1000),
            )
        )
    print(f"wrote {len(paths)} files to {out}/")

    if viewer is not None:
        viewer.set_animation(result.log)
        try:
            input(f"replaying at {viewer.url}; press Enter to quit ")
        except (EOFError, KeyboardInterrupt):
            pass
        viewer.close()
    return 0 if m.completed else 1


if __name__ == "__main__":
    raise SystemExit(main())
