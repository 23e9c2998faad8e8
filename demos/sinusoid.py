"""The thesis's sinusoid on the KUKA LBR4p, tracked by the local method with time scaling in
MuJoCo: four periods of a 0.1 m sine along the start tool frame's x axis.

    python demos/sinusoid.py             # figures and an HTML replay in results/demos/sinusoid/
    python demos/sinusoid.py --viewer    # watch the arm live in the browser (URL printed)
    python demos/sinusoid.py --short     # quick headless run (what CI executes)
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

import dqcontrol
from dqcontrol.controllers import LocalController
from dqcontrol.model import LBR4P_Q0
from dqcontrol.sim import run_mujoco
from dqcontrol.trajectories import Sinusoid
from dqcontrol.viz.figures import plot_run
from dqcontrol.viz.meshcat_viewer import MeshcatViewer, export_replay_html

VELOCITY_LIMITS = np.pi * np.array([1.0, 1.0, 1.0, 1.0, 2.5, 2.5, 2.5])  # the thesis's [rad/s]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--short", action="store_true", help="quick headless run (for CI)")
    parser.add_argument("--viewer", action="store_true", help="show the robot in the browser")
    parser.add_argument("--duration", type=float, default=4.0, help="T_tot [s] (default 4)")
    parser.add_argument("--out", default="results/demos/sinusoid", help="output folder")
    args = parser.parse_args(argv)

    robot = dqcontrol.load_lbr4p()
    # x(σ) = v σ, z(σ) = A sin(Ω_x v σ) in the start tool frame (thesis eq. 5.3)
    sinusoid = Sinusoid(duration_s=args.duration, amplitude_m=0.1, omega_x_rad_per_m=60.0)
    controller = LocalController(
        robot, sinusoid, period_s=0.05, velocity_limits=VELOCITY_LIMITS, acceleration_limit=10.0
    )

    viewer = MeshcatViewer(robot, q=LBR4P_Q0) if args.viewer else None
    result = run_mujoco(
        controller, LBR4P_Q0, on_sample=viewer.follow(controller) if viewer else None
    )

    m = result.metrics
    print(
        f"sinusoid, T_tot = {args.duration:g} s, local method, MuJoCo: completed={m.completed}, "
        f"execution time {m.execution_time_s:.3f} s (ratio {m.execution_ratio:.3f}), "
        f"e_mean {m.e_mean:.5f}, max path deviation {1e3 * m.path_deviation_max_m:.2f} mm, "
        f"s_mean {m.s_mean:.3f}"
    )

    out = Path(args.out)
    paths = plot_run(
        result.log,
        out,
        name="local",
        trajectory=controller.trajectory,
        figures=("path_2d", "translation") if args.short else None,
        dpi=60 if args.short else 110,
    )
    paths.append(
        export_replay_html(
            robot,
            result.log,
            out / "local_replay.html",
            path_points=controller.trajectory.path_positions(1000),
            fps=10 if args.short else 30,
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
