"""The four controllers side by side on the fast circle (T_tot = 1 s, the thesis's hardest):
proportional, local, predictive (p = 6 and p = 10) and predictive without time scaling, in
MuJoCo with the thesis's bounds. Prints a table and draws one comparison figure.

    python demos/compare_controllers.py            # results/demos/compare/comparison.png
    python demos/compare_controllers.py --viewer   # each run live in the browser
    python demos/compare_controllers.py --short    # local vs p = 10 only, headless (CI)
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

import dqcontrol
from dqcontrol.controllers import (
    LocalController,
    PredictiveController,
    PredictiveNoScalingController,
    ProportionalController,
)
from dqcontrol.model import LBR4P_Q0
from dqcontrol.sim import run_mujoco
from dqcontrol.trajectories import Circle
from dqcontrol.viz.figures import plot_comparison
from dqcontrol.viz.meshcat_viewer import MeshcatViewer

BOUNDS = {
    "velocity_limits": np.pi * np.array([1.0, 1.0, 1.0, 1.0, 2.5, 2.5, 2.5]),  # [rad/s]
    "acceleration_limit": 10.0,  # [rad/s²]
}
PERIOD_S = 0.05


def make_controllers(robot, duration_s: float, short: bool) -> dict:
    """One controller per label, each with its own copy of the circle."""

    def circle():
        return Circle(duration_s, radius_m=0.1)

    controllers = {
        "local": LocalController(robot, circle(), PERIOD_S, **BOUNDS),
        "p = 10": PredictiveController(robot, circle(), PERIOD_S, num_instants=10, **BOUNDS),
    }
    if not short:
        controllers["p = 6"] = PredictiveController(
            robot, circle(), PERIOD_S, num_instants=6, **BOUNDS
        )
        controllers["no scaling, p = 10"] = PredictiveNoScalingController(
            robot, circle(), PERIOD_S, num_instants=10, **BOUNDS
        )
        controllers["proportional"] = ProportionalController(robot, circle(), PERIOD_S, **BOUNDS)
    return controllers


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--short", action="store_true", help="local vs p = 10, headless (CI)")
    parser.add_argument("--viewer", action="store_true", help="show each run in the browser")
    parser.add_argument("--duration", type=float, default=1.0, help="T_tot [s] (default 1)")
    parser.add_argument("--out", default="results/demos/compare", help="output folder")
    args = parser.parse_args(argv)

    robot = dqcontrol.load_lbr4p()
    viewer = MeshcatViewer(robot, q=LBR4P_Q0) if args.viewer else None
    logs, trajectory = {}, None
    print(f"{'controller':<20} {'done':>4} {'t_exec [s]':>10} {'e_mean':>8} {'dev_max [mm]':>12}")
    for label, controller in make_controllers(robot, args.duration, args.short).items():
        on_sample = viewer.follow(controller, speed=0.5) if viewer else None
        result = run_mujoco(controller, LBR4P_Q0, on_sample=on_sample)
        m = result.metrics
        print(
            f"{label:<20} {'yes' if m.completed else 'NO':>4} {m.execution_time_s:>10.3f} "
            f"{m.e_mean:>8.5f} {1e3 * m.path_deviation_max_m:>12.2f}"
        )
        logs[label] = result.log
        trajectory = controller.trajectory  # anchored at the (common) start pose

    path = plot_comparison(
        logs,
        Path(args.out) / "comparison.png",
        trajectory=trajectory,
        dpi=60 if args.short else 110,
        title=f"LBR4p, circle, T_tot = {args.duration:g} s, T = {PERIOD_S:g} s, MuJoCo",
    )
    print(f"wrote {path}")
    if viewer is not None:
        try:
            input(f"viewer at {viewer.url}; press Enter to quit ")
        except (EOFError, KeyboardInterrupt):
            pass
        viewer.close()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
