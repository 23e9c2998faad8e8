"""Step time of each controller: an old revision's code against the working tree's.

The old code (``--baseline-rev``, default ``HEAD~1``) is checked out with ``git worktree add
--detach`` into a temporary folder (removed at the end); the new code is this repository's
working tree (or ``--new-src``). Both run with this Python in subprocesses (``PYTHONPATH`` =
the one or the other source tree), in interleaved rounds: each round starts a fresh
subprocess per version and times every controller's closed loop in blocks of ``--block``
steps, the old and the new code taking turns block by block (old-new, new-old, ...; which
version starts alternates between rounds too), so that both see the same load of the
shared machine.

The loop is the one of ``dqcontrol bench`` (``dqcontrol/bench.py``, ``step_times``): the
LBR4p from ``LBR4P_Q0`` on the 2 s circle (``Circle(2.0)``), ``T = 1 ms``, the thesis's
bounds (``|qd| <= pi [1,1,1,1,2.5,2.5,2.5] rad/s``, ``|qdd| <= 10 rad/s^2``), kinematic
integration ``q += T qd_command``, the controller reset where the task ends. Each controller
is built and run for ``--warmup`` steps untimed (imports, Numba cache loads or compilation,
first solver calls), then reset to ``q0`` and run for ``--steps`` timed steps: each step's
wall time around ``step(q)`` (``time.perf_counter``), and its ``diagnostics.step_time_s``
and ``.solve_time_s``.

Reported per controller: the median step time of the old and the new code (median over the
rounds of each round's median; and the fastest round's), the ratio new/old (median over
all blocks of the ratio of the two versions' block medians: the same steps of the same
loop, timed back to back; with the min-max over the rounds of each round's median ratio),
and the step / QP-solve ratio (median ``step_time_s`` / median ``solve_time_s`` of the
controller's own diagnostics). The end state of each timed loop is compared between the
versions (the same closed loop ends bit-equal when the code computes the same commands).

The timing child uses only API present in both versions: the controllers' constructors,
``reset(q0)``, ``step(q)`` -> result ``.qd_command``, ``.diagnostics.step_time_s`` /
``.solve_time_s``, ``.done``; ``dqcontrol.model.load_lbr4p``, ``LBR4P_Q0``,
``dqcontrol.trajectories.Circle``.

Examples::

    python benchmarks/bench_before_after.py --baseline-rev 5af8182 --json bench_ba.json
    python benchmarks/bench_before_after.py --controllers local,p10 --rounds 3 \\
        --extra-new 'core_p10=dqcontrol.controllers.x:NewController:{"num_instants": 10}'

The machine is shared: run it alone (it is niced, ``--nice``), and read a ratio against the
spread of the rounds; the same code against itself shows the noise floor of the method.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

#: A kwargs key the timing child takes out: the controller gets the collision limit of
#: ``dqcontrol bench``'s cell (a ball, a crate, the table, and self-collision).
COLLISION_KEY = "__collision__"
#: Options given only to a version whose constructor takes them: ``end="at_speed"`` asks
#: the path-following controller that ends at rest by default for what the code before
#: that default did.
IF_KNOWN_KEY = "__if_known__"
#: Controllers of both versions: name -> (class in dqcontrol.controllers, extra kwargs).
CONTROLLERS: dict[str, tuple[str, dict]] = {
    "local": ("LocalController", {}),
    "predictive_p6": ("PredictiveController", {"num_instants": 6}),
    "predictive_p10": ("PredictiveController", {"num_instants": 10}),
    "predictive_noscale_p10": ("PredictiveNoScalingController", {"num_instants": 10}),
    "proportional": ("ProportionalController", {}),
    "path_following_p10": ("PathFollowingController", {"num_intervals": 10}),
    "path_following_p10_dynamics": (
        "PathFollowingController",
        {"num_intervals": 10, "acceleration_limit": "dynamics"},
    ),
    "path_following_p10_collision": (
        "PathFollowingController",
        {"num_intervals": 10, COLLISION_KEY: True},
    ),
    "path_following_p10_at_speed": (
        "PathFollowingController",
        {"num_intervals": 10, IF_KNOWN_KEY: {"end": "at_speed"}},
    ),
}

ALIASES = {
    "p6": "predictive_p6",
    "p10": "predictive_p10",
    "noscale_p10": "predictive_noscale_p10",
    "noscale": "predictive_noscale_p10",
    "pf": "path_following_p10",
    "pf10": "path_following_p10",
    "pf_dynamics": "path_following_p10_dynamics",
    "pf_collision": "path_following_p10_collision",
    "pf_at_speed": "path_following_p10_at_speed",
}
PERIOD_S = 0.001
CIRCLE_S = 2.0

#: The timing child: the code under test on PYTHONPATH, argv[1] a JSON job. It builds and
#: warms up every controller, prints READY, then runs "RUN name n" (n more timed steps of
#: that controller's closed loop, answered OK) until "END" (answered RESULT json).
CHILD = r"""
import importlib, inspect, json, os, sys, time
import numpy as np

job = json.loads(sys.argv[1])
import dqcontrol
src = os.path.realpath(job["src"])
where = os.path.realpath(dqcontrol.__file__)
if not where.startswith(os.path.join(src, "dqcontrol") + os.sep):
    sys.exit(f"dqcontrol imported from {where}, expected under {src}")
from dqcontrol.model import LBR4P_Q0, load_lbr4p
from dqcontrol.trajectories import Circle

robot = load_lbr4p()
q0 = np.array(LBR4P_Q0, dtype=float)
period = job["period_s"]
common = {
    "velocity_limits": np.pi * np.array([1, 1, 1, 1, 2.5, 2.5, 2.5]),
    "acceleration_limit": 10.0,
}
perf = time.perf_counter


def cell_limit():
    from dqcontrol.controllers.limits.collision import CollisionLimit
    from dqcontrol.model.collision import Box, CollisionModel, HalfSpace, Sphere

    tool = robot.placement(q0).translation
    cell = (
        Sphere(name="ball", position_m=(0.2245, -0.2559, 0.9519), radius_m=0.05),
        Box(name="crate", position_m=tuple(tool + [0.0, 0.25, -0.1]), size_m=(0.1, 0.1, 0.2)),
        HalfSpace(name="table", normal=(0.0, 0.0, 1.0), offset_m=float(tool[2] - 0.3)),
    )
    return CollisionLimit(CollisionModel(robot, cell, self_collision=True))


class Loop:
    def __init__(self, spec):
        cls = getattr(importlib.import_module(spec["module"]), spec["cls"])
        kwargs = dict(common, **spec["kwargs"])
        if kwargs.pop("__collision__", False):
            kwargs["extra_limits"] = (cell_limit(),)
        for name, value in kwargs.pop("__if_known__", {}).items():
            if name in inspect.signature(cls).parameters:  # an option the old code lacks
                kwargs[name] = value
        self.ctrl = cls(robot, Circle(job["circle_s"]), period, **kwargs)
        self.wall, self.step, self.solve = [], [], []
        self.q = q0.copy()
        self.ctrl.reset(self.q)
        self.advance(job["warmup"], False)
        self.q = q0.copy()
        self.ctrl.reset(self.q)

    def advance(self, n, timed):
        ctrl, q = self.ctrl, self.q
        for _ in range(n):
            t0 = perf()
            res = ctrl.step(q)
            t1 = perf()
            if timed:
                d = res.diagnostics
                self.wall.append(t1 - t0)
                self.step.append(float(d.step_time_s))
                self.solve.append(float(d.solve_time_s))
            q = q + period * res.qd_command
            if ctrl.done:
                ctrl.reset(q)
        self.q = q


def say(text):
    sys.stdout.write(text + "\n")
    sys.stdout.flush()


loops = {spec["name"]: Loop(spec) for spec in job["controllers"]}
say("READY")
for line in sys.stdin:
    cmd = line.split()
    if cmd and cmd[0] == "RUN":
        loops[cmd[1]].advance(int(cmd[2]), True)
        say("OK")
    elif cmd and cmd[0] == "END":
        break
out = {"dqcontrol": where, "controllers": {}}
for name, lp in loops.items():
    out["controllers"][name] = {
        "wall_s": lp.wall,
        "step_time_s": lp.step,
        "solve_time_s": lp.solve,
        "q_end": [float.hex(float(x)) for x in lp.q],
    }
say("RESULT " + json.dumps(out))
"""


def _git(repo: Path, *args: str) -> str:
    return subprocess.run(
        ["git", "-C", str(repo), *args], check=True, capture_output=True, text=True
    ).stdout.strip()


def _parse_extra(text: str) -> dict:
    """``NAME=module:Class[:kwargs-json]`` -> controller spec."""
    name, sep, rest = text.partition("=")
    parts = rest.split(":", 2)
    if not sep or not name or len(parts) < 2 or not parts[0] or not parts[1]:
        raise argparse.ArgumentTypeError(
            f"--extra-new wants NAME=module:Class[:json], got {text!r}"
        )
    kwargs = json.loads(parts[2]) if len(parts) == 3 and parts[2] else {}
    if not isinstance(kwargs, dict):
        raise argparse.ArgumentTypeError(f"--extra-new kwargs must be a JSON object: {text!r}")
    return {"name": name, "module": parts[0], "cls": parts[1], "kwargs": kwargs, "extra": True}


def _specs(names: list[str]) -> list[dict]:
    out = []
    for name in names:
        cls, kwargs = CONTROLLERS[name]
        out.append({"name": name, "module": "dqcontrol.controllers", "cls": cls, "kwargs": kwargs})
    return out


class Child:
    """A timing subprocess of one code version (see :data:`CHILD`)."""

    def __init__(self, python: str, child: Path, src: Path, specs: list[dict], args, env):
        job = {
            "src": str(src),
            "controllers": [{k: s[k] for k in ("name", "module", "cls", "kwargs")} for s in specs],
            "period_s": PERIOD_S,
            "circle_s": CIRCLE_S,
            "warmup": args.warmup,
        }
        self.src = src
        self.err = tempfile.TemporaryFile(mode="w+")
        self.proc = subprocess.Popen(
            [python, str(child), json.dumps(job)],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=self.err,
            text=True,
            env=dict(env, PYTHONPATH=str(src)),
        )
        self.expect("READY")

    def expect(self, prefix: str) -> str:
        """The child's next line starting with ``prefix`` (other output is skipped)."""
        for line in self.proc.stdout:
            if line.startswith(prefix):
                return line[len(prefix) :].strip()
        self.proc.wait()
        self.err.seek(0)
        raise RuntimeError(
            f"timing child failed (PYTHONPATH={self.src}, exit {self.proc.returncode}):\n"
            f"{self.err.read()[-3000:]}"
        )

    def run(self, name: str, steps: int) -> None:
        self.proc.stdin.write(f"RUN {name} {steps}\n")
        self.proc.stdin.flush()
        self.expect("OK")

    def finish(self) -> dict:
        self.proc.stdin.write("END\n")
        self.proc.stdin.flush()
        out = json.loads(self.expect("RESULT "))
        self.proc.wait()
        self.err.close()
        return out

    def kill(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()


def _run_round(python, child, srcs, specs, extras, args, env, order) -> dict:
    """One round: a fresh child per version (started one after the other), then every
    controller's timed loop in blocks of ``args.block`` steps, alternating the versions
    block by block (ABBA); returns each version's raw per-step figures."""
    extra_names = {e["name"] for e in extras}
    children: dict[str, Child] = {}
    try:
        for version in order:
            more = extras if version == "new" else []
            children[version] = Child(python, child, srcs[version], specs + more, args, env)
        for spec in specs + extras:
            done = 0
            b = 0
            while done < args.steps:
                n = min(args.block, args.steps - done)
                for version in order if b % 2 == 0 else order[::-1]:
                    if version == "old" and spec["name"] in extra_names:
                        continue
                    children[version].run(spec["name"], n)
                done += n
                b += 1
        return {version: children[version].finish() for version in order}
    finally:
        for c in children.values():
            c.kill()


def _median(values) -> float | None:
    values = [v for v in values if v is not None]
    return statistics.median(values) if values else None


def _p90(values: list[float]) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(0.9 * len(ordered)))]


def _blocks(values: list[float], size: int) -> list[float]:
    return [statistics.median(values[i : i + size]) for i in range(0, len(values), size)]


def _summarize(rounds: list[dict], names: list[str], extra: set[str], block: int) -> dict:
    out = {}
    for name in names:
        entry: dict = {"extra_new": name in extra}
        for version in ("old", "new"):
            if version == "old" and name in extra:
                continue
            per = [r[version]["controllers"][name] for r in rounds]
            walls = [statistics.median(p["wall_s"]) for p in per]
            steps = [statistics.median(p["step_time_s"]) for p in per]
            solves = [statistics.median(p["solve_time_s"]) for p in per]
            entry[version] = {
                "wall_median_us": 1e6 * statistics.median(walls),
                "wall_best_round_us": 1e6 * min(walls),
                "wall_round_medians_us": [1e6 * w for w in walls],
                "wall_p90_us": 1e6 * statistics.median(_p90(p["wall_s"]) for p in per),
                "step_time_s_median_us": 1e6 * statistics.median(steps),
                "solve_time_s_median_us": 1e6 * statistics.median(solves),
                "step_over_solve": _median(
                    st / so if so > 0 else None for st, so in zip(steps, solves, strict=True)
                ),
                "q_end_rounds": [p["q_end"] for p in per],
            }
        if name not in extra:
            o, n = entry["old"], entry["new"]
            round_ratios, all_ratios = [], []
            for r in rounds:
                bo = _blocks(r["old"]["controllers"][name]["wall_s"], block)
                bn = _blocks(r["new"]["controllers"][name]["wall_s"], block)
                ratios = [y / x for x, y in zip(bo, bn, strict=True)]
                all_ratios += ratios
                round_ratios.append(statistics.median(ratios))
            entry["ratio_new_over_old"] = statistics.median(all_ratios)
            entry["ratio_rounds"] = round_ratios
            entry["ratio_of_medians"] = n["wall_median_us"] / o["wall_median_us"]
            old_step = o["step_time_s_median_us"]
            entry["ratio_step_time_s"] = (
                n["step_time_s_median_us"] / old_step if old_step > 0 else None
            )
            entry["same_end_state"] = o["q_end_rounds"] == n["q_end_rounds"]
        out[name] = entry
    return out


def format_table(summary: dict, meta: dict) -> str:
    lines = [
        f"old: {meta['old_label']}",
        f"new: {meta['new_label']}",
        f"{meta['rounds']} rounds, each a fresh subprocess per version; per controller and "
        f"round {meta['steps']} timed steps (after {meta['warmup']} untimed) in blocks of "
        f"{meta['block']}, old and new alternating block by block (ABBA)",
        f"LBR4p from LBR4P_Q0, circle {CIRCLE_S:g} s, T = {PERIOD_S * 1e3:g} ms, kinematic "
        "loop; load average before/after: "
        + " / ".join(f"{a:.2f}" for a in (meta["load_avg_start"][0], meta["load_avg_end"][0])),
        "",
        f"{'controller':24s} {'old µs':>8s} {'new µs':>8s} {'new/old':>8s} {'rounds':>13s} "
        f"{'best old':>8s} {'best new':>8s} {'old st/so':>9s} {'new st/so':>9s}  end state",
    ]

    def f(v, spec):
        return "—" if v is None else format(v, spec)

    for name, e in summary.items():
        n = e["new"]
        if e["extra_new"]:
            lines.append(
                f"{name:24s} {'—':>8s} {n['wall_median_us']:8.1f} {'—':>8s} {'':>13s} "
                f"{'—':>8s} {n['wall_best_round_us']:8.1f} "
                f"{'—':>9s} {f(n['step_over_solve'], '9.2f'):>9s}  (new only)"
            )
            continue
        o = e["old"]
        lo, hi = min(e["ratio_rounds"]), max(e["ratio_rounds"])
        lines.append(
            f"{name:24s} {o['wall_median_us']:8.1f} {n['wall_median_us']:8.1f} "
            f"{e['ratio_new_over_old']:8.3f} {f'{lo:.3f}-{hi:.3f}':>13s} "
            f"{o['wall_best_round_us']:8.1f} {n['wall_best_round_us']:8.1f} "
            f"{f(o['step_over_solve'], '9.2f'):>9s} {f(n['step_over_solve'], '9.2f'):>9s}  "
            f"{'same' if e['same_end_state'] else 'DIFFERS'}"
        )
    lines += [
        "",
        "old/new µs: median over the rounds of each round's median wall time of step(q);",
        "new/old: median over all blocks of the paired ratio new/old of the block medians",
        "(the same steps of the same loop, timed back to back); rounds: min-max over the rounds",
        "of each round's median block ratio; best: the fastest round's median; st/so: median",
        "diagnostics.step_time_s / median solve_time_s ('—': no QP); end state: each round's",
        "final q of the timed loop, old vs new, bit for bit.",
    ]
    return "\n".join(lines)


def _parser() -> argparse.ArgumentParser:
    """The command line (the module docstring is its help)."""
    parser = argparse.ArgumentParser(
        description=(__doc__ or "").split("\n\n", 1)[0],
        epilog="\n\n".join((__doc__ or "").split("\n\n")[1:]),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument(
        "--baseline-rev", default="HEAD~1", help="git revision of the old code (default HEAD~1)"
    )
    parser.add_argument(
        "--old-src",
        help="an existing source tree of the old code instead of --baseline-rev's checkout",
    )
    parser.add_argument(
        "--new-src", help="source tree of the new code (default: this repository's work tree)"
    )
    parser.add_argument(
        "--controllers",
        default=",".join(CONTROLLERS),
        help=f"comma-separated subset of {', '.join(CONTROLLERS)} (default: all)",
    )
    parser.add_argument("--rounds", type=int, default=5, help="interleaved rounds (default 5)")
    parser.add_argument(
        "--steps", type=int, default=2000, help="timed steps per controller (default 2000)"
    )
    parser.add_argument(
        "--warmup", type=int, default=200, help="untimed steps before them (default 200)"
    )
    parser.add_argument(
        "--block",
        type=int,
        default=100,
        help="steps run by one version before the other takes over (default 100)",
    )
    parser.add_argument(
        "--extra-new",
        action="append",
        default=[],
        type=_parse_extra,
        metavar="NAME=module:Class[:kwargs-json]",
        help="also time a controller of the new code only (built as Class(robot, circle, T, "
        "velocity_limits=..., acceleration_limit=10, **kwargs)); printed without a ratio",
    )
    parser.add_argument("--json", help="write the figures to this JSON file")
    parser.add_argument(
        "--nice", type=int, default=10, help="niceness of the timing (default 10; 0: none)"
    )
    return parser


def _checked(parser: argparse.ArgumentParser, args: argparse.Namespace) -> list[str]:
    """The controllers to time, by their names (aliases resolved, each once); an unknown
    one, a clashing ``--extra-new`` name or a count out of range is a usage error."""
    names = []
    for n in (x.strip() for x in args.controllers.split(",") if x.strip()):
        n = ALIASES.get(n, n)
        if n not in CONTROLLERS:
            parser.error(f"unknown controller {n!r}; choose from {', '.join(CONTROLLERS)}")
        if n not in names:
            names.append(n)
    extras = args.extra_new
    clash = [e["name"] for e in extras if e["name"] in names]
    if clash or len({e["name"] for e in extras}) < len(extras):
        parser.error(f"--extra-new names must be new and distinct: {clash}")
    if args.rounds < 1 or args.steps < 1 or args.block < 1 or args.warmup < 0:
        parser.error("--rounds, --steps and --block must be ≥ 1, --warmup ≥ 0")
    return names


def _tree_state(src: Path) -> tuple[str, bool]:
    """The tree's commit and whether its tracked files are modified."""
    try:
        head = _git(src, "rev-parse", "--short", "HEAD")
        dirty = bool(_git(src, "status", "--porcelain", "--untracked-files=no"))
    except (subprocess.CalledProcessError, OSError):
        return "not a git tree", False
    return head, dirty


def _old_tree(args: argparse.Namespace, repo: Path, tmp: Path) -> tuple[Path, str, str | None]:
    """The old code's tree (``--old-src``, or ``--baseline-rev`` checked out as a worktree
    in ``tmp``), its label and its commit."""
    if args.old_src:
        old_src = Path(args.old_src).resolve()
        return old_src, f"{old_src} (given tree)", None
    old_commit = _git(repo, "rev-parse", "--verify", f"{args.baseline_rev}^{{commit}}")
    worktree = tmp / "old"
    _git(repo, "worktree", "add", "--detach", str(worktree), old_commit)
    return worktree, f"{args.baseline_rev} = {old_commit[:10]} (worktree {worktree})", old_commit


def _timed_rounds(args, names, srcs: dict, tmp: Path, env: dict) -> list[dict]:
    """Prime both trees' Numba caches, then time ``args.rounds`` interleaved rounds (which
    version starts and the controllers' order rotate)."""
    python = sys.executable
    child = tmp / "bench_child.py"
    child.write_text(CHILD)
    base, extras = _specs(names), args.extra_new
    # prime each tree's Numba cache (compilation is never timed, but would load the
    # machine while the other version is timed)
    prime = argparse.Namespace(warmup=5, steps=5, block=5)
    t0 = time.perf_counter()
    _run_round(python, child, srcs, base, extras, prime, env, ("old", "new"))
    print(f"primed both trees in {time.perf_counter() - t0:.1f} s", flush=True)
    rounds = []
    for r in range(args.rounds):
        order = ("old", "new") if r % 2 == 0 else ("new", "old")
        k = r % len(base)  # rotate the controllers' order: none always runs first
        res = _run_round(python, child, srcs, base[k:] + base[:k], extras, args, env, order)
        rounds.append(res)
        line = ", ".join(
            f"{n} {1e6 * statistics.median(res['old']['controllers'][n]['wall_s']):.0f}/"
            f"{1e6 * statistics.median(res['new']['controllers'][n]['wall_s']):.0f}"
            for n in names
        )
        print(f"round {r + 1}/{args.rounds}, median µs old/new: {line}", flush=True)
    return rounds


def _removed(repo: Path, tmp: Path) -> None:
    """The old code's worktree (if one was made) and the temporary folder, removed."""
    worktree = tmp / "old"
    if worktree.exists():
        subprocess.run(
            ["git", "-C", str(repo), "worktree", "remove", "--force", str(worktree)],
            capture_output=True,
        )
        subprocess.run(["git", "-C", str(repo), "worktree", "prune"], capture_output=True)
    shutil.rmtree(tmp, ignore_errors=True)


def main(argv: list[str] | None = None) -> int:
    parser = _parser()
    args = parser.parse_args(argv)
    names = _checked(parser, args)
    if args.nice:
        os.nice(args.nice)
    repo = Path(_git(Path(__file__).resolve().parent, "rev-parse", "--show-toplevel"))
    new_src = Path(args.new_src).resolve() if args.new_src else repo
    head, dirty = _tree_state(new_src)
    load_start = os.getloadavg()
    tmp = Path(tempfile.mkdtemp(prefix="bench_before_after_"))
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1")
    env.pop("PYTHONPATH", None)
    try:
        old_src, old_label, old_commit = _old_tree(args, repo, tmp)
        new_label = f"{new_src} (HEAD {head}{', modified' if dirty else ''})"
        print(f"old: {old_label}\nnew: {new_label}", flush=True)
        rounds = _timed_rounds(args, names, {"old": old_src, "new": new_src}, tmp, env)
    finally:
        _removed(repo, tmp)
    extra_names = [e["name"] for e in args.extra_new]
    summary = _summarize(rounds, names + extra_names, set(extra_names), args.block)
    meta = {
        "old_label": old_label, "new_label": new_label, "old_commit": old_commit,
        "new_head": head, "new_modified": dirty, "rounds": args.rounds, "steps": args.steps,
        "warmup": args.warmup, "block": args.block, "period_s": PERIOD_S,
        "circle_s": CIRCLE_S, "python": platform.python_version(),
        "platform": platform.platform(), "cpus": os.cpu_count(),
        "load_avg_start": load_start, "load_avg_end": os.getloadavg(),
    }  # fmt: skip
    print()
    print(format_table(summary, meta))
    if args.json:
        Path(args.json).write_text(
            json.dumps({"meta": meta, "controllers": summary}, indent=2) + "\n"
        )
        print(f"\nwritten: {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
