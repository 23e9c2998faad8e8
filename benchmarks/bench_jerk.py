"""What a jerk limit costs the path-following controller: execution time and step time.

The Panda (example-robot-data) with Franka's published limits (velocity, acceleration,
jerk) at ``T = 1 ms`` in the kinematic loop (``q += T qd``), on a 15 cm circle of 1 s and a
waypoint path of 1 s, the path-following controller with and without ``jerk_limit``. The
two loops run side by side, in blocks of ``--block`` steps taken in turns (which one
starts alternates), so that both see the same load of the shared machine. Reported per
case: the execution time of each (steps to ``σ = T_tot``, times ``T``; deterministic), the
largest second difference of the applied commands over ``j̄ T²``, and the median step
time (``time.perf_counter`` around ``step``) of each and their ratio (the median of the
blocks' ratios of medians).

    python benchmarks/bench_jerk.py [--block 50] [--rounds 1] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import statistics
import time

import numpy as np

import dqcontrol
from dqcontrol.controllers import PathFollowingController, single_blas_thread
from dqcontrol.model import PANDA_Q0
from dqcontrol.trajectories import Circle, WaypointTrajectory

PERIOD_S = 0.001
VELOCITY = np.array([2.175] * 4 + [2.61] * 3)
ACCELERATION = np.array([15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0])
JERK = np.array([7500.0, 3750.0, 5000.0, 6250.0, 7500.0, 10000.0, 10000.0])
WAYPOINTS_M = np.array([[0, 0, 0], [0.1, 0, 0], [0.1, 0.1, 0], [0, 0.1, 0.05]], dtype=float)


def cases() -> dict:
    return {
        "circle_1s": lambda: Circle(1.0, 0.15),
        "waypoints_1s": lambda: WaypointTrajectory(WAYPOINTS_M, duration_s=1.0),
    }


class Loop:
    """One closed kinematic loop of the controller, advanced a block at a time."""

    def __init__(self, robot, trajectory, jerk) -> None:
        self.ctrl = PathFollowingController(
            robot, trajectory, PERIOD_S, velocity_limits=VELOCITY,
            acceleration_limit=ACCELERATION, jerk_limit=jerk,
        )  # fmt: skip
        self.q = PANDA_Q0.copy()
        self.ctrl.reset(self.q)
        self.commands = [np.zeros(7), np.zeros(7)]
        self.times: list[float] = []

    def advance(self, steps: int) -> list[float]:
        block = []
        for _ in range(steps):
            if self.ctrl.done or len(self.commands) > 6000:
                break
            start = time.perf_counter()
            r = self.ctrl.step(self.q)
            block.append(time.perf_counter() - start)
            self.q = self.q + PERIOD_S * r.qd_command
            self.commands.append(r.qd_command.copy())
        self.times += block
        return block

    def summary(self) -> dict:
        u = np.array(self.commands)
        jerk = np.abs(np.diff(u, 2, axis=0)) / PERIOD_S**2
        return {
            "execution_time_s": (len(u) - 2) * PERIOD_S,
            "done": self.ctrl.done,
            "max_jerk_over_limit": float(np.max(jerk / JERK)),
            "median_step_ms": 1e3 * statistics.median(self.times),
        }


def run_case(robot, make, block: int) -> dict:
    loops = {"without": Loop(robot, make(), None), "with": Loop(robot, make(), JERK)}
    ratios, turn = [], 0
    while not all(lp.ctrl.done for lp in loops.values()):
        order = ("with", "without") if turn % 2 else ("without", "with")
        times = {name: loops[name].advance(block) for name in order}
        if times["with"] and times["without"]:
            ratios.append(statistics.median(times["with"]) / statistics.median(times["without"]))
        turn += 1
        if turn > 200:
            break
    out = {name: lp.summary() for name, lp in loops.items()}
    out["step_time_ratio"] = statistics.median(ratios)
    out["execution_time_ratio"] = (
        out["with"]["execution_time_s"] / out["without"]["execution_time_s"]
    )
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--block", type=int, default=50, help="steps per turn (default 50)")
    parser.add_argument("--rounds", type=int, default=1, help="runs of each case (default 1)")
    parser.add_argument("--json", help="write the results to this file")
    args = parser.parse_args()
    robot = dqcontrol.load_panda()
    results: dict = {}
    with single_blas_thread():
        for name, make in cases().items():
            Loop(robot, make(), JERK).advance(200)  # warm-up: Numba caches, first solves
            rounds = [run_case(robot, make, args.block) for _ in range(args.rounds)]
            results[name] = rounds
            for r in rounds:
                print(
                    f"{name}: execution {r['without']['execution_time_s']:.3f} s -> "
                    f"{r['with']['execution_time_s']:.3f} s ({r['execution_time_ratio']:.3f}x); "
                    f"max jerk/limit {r['without']['max_jerk_over_limit']:.2f} -> "
                    f"{r['with']['max_jerk_over_limit']:.4f}; step "
                    f"{r['without']['median_step_ms']:.3f} -> {r['with']['median_step_ms']:.3f} "
                    f"ms (ratio {r['step_time_ratio']:.3f})"
                )
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(results, fh, indent=2)


if __name__ == "__main__":
    main()
