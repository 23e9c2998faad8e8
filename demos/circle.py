"""The thesis's circle on the KUKA LBR4p, tracked by the predictive controller (p = 10) in
MuJoCo.

    python demos/circle.py             # figures and an HTML replay in results/demos/circle/
    python demos/circle.py --viewer    # watch the arm live in the browser (URL printed)
    python demos/circle.py --short     # quick headless run (what CI executes)
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

import dqcontrol
from dqcontrol.controllers import PredictiveController
from dqcontrol.model import LBR4P_Q0
from dqcontrol.sim import run_mujoco
from dqcontrol.trajectories import Circle
from dqcontrol.viz.figures import plot_run
from dqcontrol.viz.meshcat_viewer import MeshcatViewer, export_replay_html

#: The thesis's bounds: |qd| ≤ π·[1, 1, 1, 1, 2.5, 2.5, 2.5] rad/s and |qdd| ≤ 10 rad/s².
VELOCITY_LIMITS = np.pi * np.array([1.0, 1.0, 1.0, 1.0, 2.5, 2.5, 2.5])
ACCELERATION_LIMIT = 10.0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--short", action="store_true", help="quick headless run (for CI)")
    parser.add_argument("--viewer", action="store_true", help="show the robot in the browser")
    parser.add_argument("--duration", type=float, default=2.0, help="T_tot [s] (default 2)")
    parser.add_argument("--out", default="results/demos/circle", help="output folder")
    args = parser.parse_args(argv)

    robot = dqcontrol.load_lbr4p()  # robots/lbr4p/lbr4p.urdf, end effector lbr4p_flange
    circle = Circle(duration_s=args.duration, radius_m=0.1)  # anchored at the start pose
    controller = PredictiveController(
        robot,
        circle,
        period_s=0.05,
        num_instants=10,
        horizon_s=1.0,
        velocity_limits=VELOCITY_LIMITS,
        acceleration_limit=ACCELERATION_LIMIT,
    )

    viewer = MeshcatViewer(robot, q=LBR4P_Q0) if args.viewer else None
    on_sample = viewer.follow(controller) if viewer else None  # live: robot, trace, target
    result = run_mujoco(controller, LBR4P_Q0, on_sample=on_sample)

    m = result.metrics
    print(
        f"circle, T_tot = {args.duration:g} s, p = 10, MuJoCo: completed={m.completed}, "
        f"execution time {m.execution_time_s:.3f} s, e_mean {m.e_mean:.5f}, "
        f"max path deviation {1e3 * m.path_deviation_max_m:.2f} mm, s_mean {m.s_mean:.3f}, "
        f"peak torque {m.torque_peak_nm:.1f} N·m"
    )

    out = Path(args.out)
    figures = ("path_2d", "scaling") if args.short else None  # None: the whole set
    paths = plot_run(
        result.log,
        out,
        name="p10",
        trajectory=controller.trajectory,
        figures=figures,
        dpi=60 if args.short else 110,
    )
    paths.append(
        export_replay_html(
            robot,
            result.log,
            out / "p10_replay.html",
            path_points=controller.trajectory.path_positions(1000),
            fps=10 if args.short else 30,
        )
    )
    print(f"wrote {len(paths)} files to {out}/ (open p10_replay.html in a browser)")

    if viewer is not None:
        viewer.set_animation(result.log)  # the browser now loops the run
        try:
            input(f"replaying at {viewer.url}; press Enter to quit ")
        except (EOFError, KeyboardInterrupt):
            pass
        viewer.close()
    return 0 if m.completed else 1


if __name__ == "__main__":
    raise SystemExit(main())
