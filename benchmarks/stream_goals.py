"""The streaming goals, measured (docs/theory.md §12): the path-following controller with the
collision limit planned every ``T_p`` in its own process and streamed at 1 kHz on the wall
clock, against the synchronous controller at ``T = 1 ms``.

Three tasks, 10 s of motion in all: the LBR4p's 3 s circle (``dqcontrol bench``'s cell: a
ball at the elbow, a crate beside the path, the table) and 4 s sinusoid (the ball and the
table: the sinusoid passes where the crate stands, and the controller rightly stops before
it), and the Franka Panda's 3 s waypoint path with the tool turning (a table under it);
self-collision in every one. For each:

* **synchronous, stepped**: the controller solving every period, in the kinematic loop and
  in MuJoCo (the reference execution time and deviation);
* **streamed, kinematic loop, wall clock**: ``run_loop(realtime=True)`` against the ideal
  integration in this process;
* **streamed, over the bridge, wall clock**: ``dqcontrol sim-server`` (MuJoCo) in its own
  process, ``BridgeDriver`` and ``run_loop(realtime=True)`` here, as ``dqcontrol run
  --connect ... --realtime --period 0.001 --plan-period T_P`` runs it.

The plan period is chosen as ``dqcontrol run --plan-period auto`` chooses it (twice the p99
of the synchronous step time, at least 5 ms, a whole number of periods) unless
``--plan-period`` is given.
Beside every wall-clock run a sleeper in its own process asks for 1 ms sleeps and records
how much longer each took: a late command whose sample overlaps a measured host stall of
≥ 2.5 ms is counted as the host's.

``--rt-priority N`` runs the loop's thread in ``SCHED_FIFO``
(``run_loop(realtime_priority=N)``, ``dqcontrol run --rt-priority N``) and the sim-server as
``chrt -f N`` (a real arm's controller is a real-time task too).

Printed per run: late commands (written after their period's end; the host's among them),
commands the streamer had ready after their period, missed deadlines of the loop (a
sample's work from its measurement to its command) and the periods it skipped after them, the
loop's start jitter (median, p99, max), the path deviation (task and stop), the execution
time against the synchronous run, the plan period, the planner's and the streamer's step
times; ``--json FILE`` writes them. Not a unit test (it runs for about a minute).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from bench import cell_obstacles  # benchmarks/ is on the path of a script run from it

import dqcontrol
from dqcontrol.controllers.limits.collision import CollisionLimit
from dqcontrol.controllers.path_following.controller import PathFollowingController
from dqcontrol.dq import qfrom_axis_angle
from dqcontrol.model import LBR4P_Q0, PANDA_Q0, load_lbr4p, load_panda
from dqcontrol.model.collision import CollisionModel, HalfSpace
from dqcontrol.sim import KinematicDriver, MujocoDriver, run_loop
from dqcontrol.sim.bridge import BridgeDriver
from dqcontrol.sim.mujoco_sim import SERVO_TIME_CONSTANT_S
from dqcontrol.streaming import streamed
from dqcontrol.streaming.planner import choose_plan_period
from dqcontrol.trajectories import Circle, Sinusoid, WaypointTrajectory

PERIOD_S = 1e-3
#: A sleeper's overrun at least this long is a stall of the host [s].
HOST_STALL_S = 2.5e-3

#: The sleeper: 1 ms sleeps until SIGTERM, then the overruns ≥ argv[1] as JSON
#: ``[(end, overrun), ...]`` on ``time.perf_counter``'s clock (CLOCK_MONOTONIC: the same
#: in every process of the machine).
SLEEPER = r"""
import json, signal, sys, time
limit = float(sys.argv[1])
stalls = []

def done(*_):
    print(json.dumps(stalls), flush=True)
    sys.exit(0)

signal.signal(signal.SIGTERM, done)
print("ready", flush=True)
t = time.perf_counter()
while True:
    time.sleep(1e-3)
    now = time.perf_counter()
    if now - t - 1e-3 >= limit:
        stalls.append((now, now - t - 1e-3))
    t = now
"""


@dataclass(frozen=True)
class Task:
    name: str
    robot: object
    q0: np.ndarray
    trajectory: object
    obstacles: tuple
    robot_option: str


def _panda_waypoints(duration_s: float) -> WaypointTrajectory:
    z = np.array([0.0, 0.0, 1.0])
    return WaypointTrajectory(
        positions_m=[[0.0, 0.0, 0.0], [0.08, 0.05, 0.0], [0.12, -0.05, 0.03], [0.0, 0.0, 0.0]],
        orientations=[qfrom_axis_angle(z, np.radians(a)) for a in (0.0, 30.0, -20.0, 0.0)],
        duration_s=duration_s,
    )


def tasks() -> list[Task]:
    lbr4p, panda = load_lbr4p(), load_panda()
    tool = panda.placement(PANDA_Q0).translation
    table = (HalfSpace(name="table", normal=(0.0, 0.0, 1.0), offset_m=float(tool[2] - 0.3)),)
    cell = cell_obstacles(lbr4p)
    return [
        Task("lbr4p circle 3 s", lbr4p, LBR4P_Q0, Circle(3.0), cell, "lbr4p"),
        Task("lbr4p sinusoid 4 s", lbr4p, LBR4P_Q0, Sinusoid(4.0), (cell[0], cell[2]), "lbr4p"),
        Task("panda waypoints 3 s", panda, PANDA_Q0, _panda_waypoints(3.0), table, "panda"),
    ]


def controller(task: Task, period_s: float, mujoco: bool) -> PathFollowingController:
    """The path-following controller with the collision limit (told of MuJoCo's servo, as
    ``dqcontrol run`` tells it)."""
    limit = CollisionLimit(CollisionModel(task.robot, task.obstacles, self_collision=True))
    extra = {"servo_time_constant_s": SERVO_TIME_CONSTANT_S} if mujoco else {}
    return PathFollowingController(
        task.robot, task.trajectory, period_s, extra_limits=(limit,), **extra
    )


def plan_period(task: Task) -> float:
    """``--plan-period auto``: twice the p99 of 40 steps' time (the first 10 left out), at
    least 5 ms."""
    ctrl = controller(task, PERIOD_S, mujoco=False)
    ctrl.reset(task.q0)
    q, times = task.q0.copy(), []
    for _ in range(40):
        start = time.perf_counter()
        q = q + PERIOD_S * ctrl.step(q).qd_command
        times.append(time.perf_counter() - start)
    return choose_plan_period(times[10:], PERIOD_S)


def _sleeper() -> subprocess.Popen:
    proc = subprocess.Popen(
        [sys.executable, "-c", SLEEPER, str(HOST_STALL_S)],
        stdout=subprocess.PIPE,
        text=True,
    )
    assert proc.stdout is not None and proc.stdout.readline() == "ready\n"
    return proc


def _sim_server(task: Task, priority: int | None, transport: str) -> tuple[subprocess.Popen, str]:
    code = "from dqcontrol.cli import main; raise SystemExit(main())"
    root = str(Path(dqcontrol.__file__).resolve().parents[1])
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([root, os.environ.get("PYTHONPATH", "")])}
    chrt = [] if priority is None else ["chrt", "-f", str(priority)]
    proc = subprocess.Popen(
        [*chrt, sys.executable, "-c", code, "sim-server", "--robot", task.robot_option,
         "--port", "0", "--period", str(PERIOD_S), "--no-progress", "--transport", transport],
        stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, env=env,
    )  # fmt: skip
    assert proc.stdout is not None
    line = proc.stdout.readline()
    return proc, line.rsplit(" on ", 1)[1].strip()


def _figures(result, ends_s: list[float], stalls: list) -> dict:
    """Late commands (and the host's among them), the loop's timing and the path."""
    log, m, stop = result.log, result.metrics, result.log.meta["stop"]
    late_s = np.asarray(log.lateness_s, dtype=float)
    ends = np.asarray(ends_s)  # each sample's end (its state read and recorded)
    host = 0
    for k in stop.get("late_command_samples", []):
        begin = ends[k - 1] if k > 0 else ends[0] - 2 * PERIOD_S
        host += any(t - over <= ends[k] and t >= begin for t, over in stalls)
    stream = log.meta.get("stream", {})
    playout = stream.get("playout", "")
    waited = re.search(r"no new plan for (\d+) ms: .* from sample (\d+)", playout)
    playout_host = False
    if waited:
        k = min(int(waited[2]), len(ends) - 1)
        begin = ends[max(k - round(int(waited[1]) * 1e-3 / PERIOD_S), 0)]
        playout_host = any(t - over <= ends[k] and t >= begin for t, over in stalls)
    return {
        "playout_during_host_stall": playout_host,
        "late_commands": int(stop.get("late_commands", 0)),
        "late_ready": int(np.count_nonzero(late_s > PERIOD_S)),
        "late_during_host_stalls": int(host),
        "skipped_periods": int(stop.get("skipped_periods", 0)),
        "missed_deadlines": int(stop.get("missed_deadlines", 0)),
        "reason": stop["reason"],
        "jitter_median_ms": stop.get("jitter_median_ms"),
        "jitter_p99_ms": stop.get("jitter_p99_ms"),
        "jitter_max_ms": stop.get("jitter_max_ms"),
        "lateness_max_ms": float(1e3 * np.nanmax(late_s, initial=-np.inf)),
        "host_stalls": len(stalls),
        "host_stall_max_ms": max((1e3 * over for _t, over in stalls), default=0.0),
        "deviation_max_mm": 1e3 * m.path_deviation_max_m,
        "stop_deviation_max_mm": 1e3 * m.stop_path_deviation_max_m,
        "execution_s": m.execution_time_s,
        "completed": bool(m.completed),
        "planner_step_median_ms": stream.get("planner_step_median_ms"),
        "streamer_step_median_us": stream.get("streamer_step_median_us"),
        "plans_used": stream.get("plans_used"),
        "playout": playout,
        "sigma_reached_s": m.sigma_reached_s,
    }


def streamed_run(
    task: Task, plan_period_s: float, bridge: str | None, priority: int | None
) -> dict:
    """The streamed controller on the wall clock, against the ideal kinematics here or
    MuJoCo over the bridge (``bridge``: its transport), a sleeper beside it."""
    ctrl = streamed(controller(task, plan_period_s, mujoco=bridge is not None), PERIOD_S)
    server = None
    if bridge:
        server, address = _sim_server(task, priority, bridge)
        driver = BridgeDriver(address, hello_timeout_s=60.0)
    else:
        driver = KinematicDriver(task.robot, PERIOD_S)
    sleeper = _sleeper()
    ends: list[float] = []
    try:
        result = run_loop(
            ctrl, driver, q0=task.q0, realtime=True, realtime_priority=priority,
            on_sample=lambda _k, _d, _r: ends.append(time.perf_counter()),
        )  # fmt: skip
    finally:
        sleeper.terminate()
        stalls = json.loads(sleeper.communicate(timeout=30.0)[0])
        if server is not None:
            driver.close()
            server.kill()
            server.wait(timeout=10.0)
    return _figures(result, ends, stalls)


def synchronous_run(task: Task, mujoco: bool) -> dict:
    ctrl = controller(task, PERIOD_S, mujoco=mujoco)
    driver = MujocoDriver(task.robot, PERIOD_S) if mujoco else KinematicDriver(task.robot, PERIOD_S)
    result = run_loop(ctrl, driver, q0=task.q0)
    m = result.metrics
    return {
        "deviation_max_mm": 1e3 * m.path_deviation_max_m,
        "execution_s": m.execution_time_s,
        "completed": bool(m.completed),
    }


def _line(name: str, loop: str, r: dict, sync: dict) -> str:
    return (
        f"{name:22s} {loop:9s} late {r['late_commands']:4d} (host {r['late_during_host_stalls']}"
        f", ready late {r['late_ready']}), missed {r['missed_deadlines']:4d}, skipped "
        f"{r['skipped_periods']}, jitter {r['jitter_median_ms']:.3f}/"
        f"{r['jitter_p99_ms']:.3f}/{r['jitter_max_ms']:.2f} ms, stalls {r['host_stalls']} "
        f"(max {r['host_stall_max_ms']:.1f} ms) | dev {r['deviation_max_mm']:.3f} mm "
        f"(sync {sync['deviation_max_mm']:.3f}), exec {r['execution_s']:.3f} s = "
        f"{r['execution_s'] / sync['execution_s']:.3f}x sync | planner "
        f"{r['planner_step_median_ms']:.2f} ms, streamer {r['streamer_step_median_us']:.1f} us, "
        f"{r['reason']}, σ {r['sigma_reached_s']:.3f} s"
        + (f"; {r['playout']}" if r["playout"] else "")
        + (" (a host stall in that wait)" if r["playout_during_host_stall"] else "")
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").split("\n\n", 1)[0])
    parser.add_argument("--plan-period", type=float, default=None, help="T_p [s] (default: auto)")
    parser.add_argument("--no-bridge", action="store_true", help="the kinematic loop only")
    parser.add_argument(
        "--transport", choices=("udp", "tcp"), nargs="+", default=["udp"],
        help="the bridge's transport(s) (default udp)",
    )  # fmt: skip
    parser.add_argument("--rt-priority", type=int, default=None, help="SCHED_FIFO priority")
    parser.add_argument("--json", help="write the figures to this JSON file")
    args = parser.parse_args(argv)
    out: dict = {}
    for task in tasks():
        tp = args.plan_period or plan_period(task)
        sync_kin = synchronous_run(task, mujoco=False)
        rows = {"plan_period_s": tp, "sync_kinematic": sync_kin}
        rows["kinematic"] = streamed_run(task, tp, None, args.rt_priority)
        print(f"T_p = {1e3 * tp:g} ms", flush=True)
        print(_line(task.name, "kinematic", rows["kinematic"], sync_kin), flush=True)
        if not args.no_bridge:
            sync_mj = synchronous_run(task, mujoco=True)
            rows["sync_mujoco"] = sync_mj
            for transport in args.transport:
                key = f"bridge_{transport}"
                rows[key] = streamed_run(task, tp, transport, args.rt_priority)
                print(_line(task.name, key, rows[key], sync_mj), flush=True)
        out[task.name] = rows
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
