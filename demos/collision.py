"""Collision avoidance as a limit: the path-following controller on the LBR4p's circle with a
ball on the path (it stops before it, on the path) and a ball at the elbow (the elbow moves
away while the tool keeps the path), in the kinematic loop (docs/theory.md §10).

    python demos/collision.py            # figures and HTML replays in results/demos/collision/
    python demos/collision.py --viewer   # watch the runs live in the browser (URL printed)
    python demos/collision.py --short    # quick headless run (what CI executes)
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

import dqcontrol
from dqcontrol.controllers.limits.collision import CollisionLimit
from dqcontrol.controllers.path_following.controller import PathFollowingController
from dqcontrol.dq.algebra import dq_to_se3
from dqcontrol.model import LBR4P_Q0
from dqcontrol.model.collision import CollisionModel, Sphere
from dqcontrol.sim import run_kinematic
from dqcontrol.sim.mjcf_builder import replay_contacts
from dqcontrol.trajectories import Circle
from dqcontrol.viz.figures import plot_run
from dqcontrol.viz.meshcat_viewer import MeshcatViewer, export_replay_html

#: The thesis's bounds: |qd| ≤ π·[1, 1, 1, 1, 2.5, 2.5, 2.5] rad/s and |qdd| ≤ 10 rad/s².
VELOCITY_LIMITS = np.pi * np.array([1.0, 1.0, 1.0, 1.0, 2.5, 2.5, 2.5])
ACCELERATION_LIMIT = 10.0
PERIOD_S = 0.01
SAFETY_M = 0.02


def scenes(robot) -> dict[str, Sphere]:
    """A ball (r = 3 cm) on the circle at σ = 1 s, and one (r = 5 cm) in the elbow's way."""
    circle = Circle(2.0).anchored_at(robot.pose(LBR4P_Q0))
    on_path = dq_to_se3(circle.target(1.0)).translation
    return {
        "ball_on_path": Sphere(name="ball", position_m=tuple(on_path), radius_m=0.03),
        "ball_at_elbow": Sphere(name="ball", position_m=(0.2245, -0.2559, 0.9519), radius_m=0.05),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--short", action="store_true", help="quick headless run (for CI)")
    parser.add_argument("--viewer", action="store_true", help="show the robot in the browser")
    parser.add_argument("--out", default="results/demos/collision", help="output folder")
    args = parser.parse_args(argv)

    robot = dqcontrol.load_lbr4p()
    out = Path(args.out)
    viewer = MeshcatViewer(robot, q=LBR4P_Q0) if args.viewer else None
    ok = True
    written: list[Path] = []
    for name, ball in scenes(robot).items():
        collision = CollisionModel(robot, (ball,))  # the ball and self-collision
        limit = CollisionLimit(collision, safety_distance_m=SAFETY_M)
        controller = PathFollowingController(
            robot, Circle(2.0), PERIOD_S, num_intervals=6,
            velocity_limits=VELOCITY_LIMITS, acceleration_limit=ACCELERATION_LIMIT,
            extra_limits=(limit,),
        )  # fmt: skip
        result = run_kinematic(controller, LBR4P_Q0, max_time_s=2.5 if args.short else 4.0)
        log = result.log
        closest = min(collision.min_distance(q) for q in log.q)
        contacts = replay_contacts(robot, collision.obstacles, log.q)
        m = result.metrics
        print(
            f"{name}: min distance {1e3 * closest:.2f} mm (safety {1e3 * SAFETY_M:g} mm), "
            f"contacts {contacts.obstacle + contacts.self_contact}, final s {log.s[-1]:.4f}, "
            f"σ {log.sigma[-1]:.3f} of 2 s, max path deviation "
            f"{1e3 * m.path_deviation_max_m:.3f} mm, {collision.num_pairs} pairs"
        )
        ok &= closest >= SAFETY_M - 5e-4 and contacts.obstacle + contacts.self_contact == 0
        points = controller.trajectory.path_positions(1000)
        figures = ("path_2d", "scaling") if args.short else None
        written += plot_run(
            log, out, name=name, trajectory=controller.trajectory, figures=figures,
            dpi=60 if args.short else 110,
        )  # fmt: skip
        written.append(
            export_replay_html(
                robot, log, out / f"{name}_replay.html", path_points=points,
                fps=10 if args.short else 30, obstacles=collision.obstacles,
            )
        )  # fmt: skip
        if viewer is not None:
            viewer.show_obstacles(collision.obstacles)
            viewer.play(log, path_points=points)
    print(f"wrote {len(written)} files to {out}/ (open *_replay.html in a browser)")
    if viewer is not None:
        viewer.close()
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
