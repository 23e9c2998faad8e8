"""Every command of every controller over a fixed closed loop, saved for a bit-for-bit
comparison of two versions of the code.

A refactoring of the controllers must leave their commands unchanged. This script runs each
controller of a fixed list (the thesis's controllers, the path-following one with its
defaults and with the thesis's bounds, the strict priority, OSQP, each with and without the
collision limit of ``dqcontrol bench``, and the QP faults of the campaign) in the kinematic
loop on the LBR4p's 2 s circle at ``T = 1 ms`` for ``--steps`` steps, and saves every
applied command, time scaling and phase to an ``.npz``. Two files are compared with
``--compare``: the largest relative difference of each controller's arrays is printed, and
the exit status is 1 if any is above ``--rtol`` (default 0: bit for bit).

It uses only the public API (:func:`dqcontrol.registry.build_controller`, the controllers'
``reset``/``step``, :func:`dqcontrol.faults.qp_faults.contradictory`), so that an older
checkout can run it too (``PYTHONPATH=OLD_TREE python benchmarks/command_digest.py``)::

    PYTHONPATH=/tmp/old python benchmarks/command_digest.py --out old.npz
    python benchmarks/command_digest.py --out new.npz
    python benchmarks/command_digest.py --compare old.npz new.npz
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from dqcontrol.controllers import single_blas_thread
from dqcontrol.experiments.thesis import THESIS_ACCELERATION_LIMIT, THESIS_VELOCITY_LIMITS
from dqcontrol.model import LBR4P_Q0, load_lbr4p
from dqcontrol.registry import build_controller, controller_spec
from dqcontrol.trajectories import Circle

PERIOD_S = 0.001
THESIS = {
    "velocity_limits": np.array(THESIS_VELOCITY_LIMITS),
    "acceleration_limit": THESIS_ACCELERATION_LIMIT,
}
#: name -> (registry name, shared options, extra keyword arguments)
CASES: dict[str, tuple[str, dict, dict]] = {
    "local": ("local", THESIS, {}),
    "p6": ("p6", THESIS, {}),
    "p10": ("p10", THESIS, {}),
    "noscale": ("noscale", THESIS, {}),
    "proportional": ("proportional", THESIS, {}),
    "pf": ("pf", THESIS, {}),
    "pf_defaults": ("pf", {}, {}),
    "p10_strict": ("p10", THESIS, {"priority": "strict"}),
    "local_osqp": ("local", {**THESIS, "solver": "osqp"}, {}),
    "p10_osqp": ("p10", {**THESIS, "solver": "osqp"}, {}),
    "pf_osqp": ("pf", {**THESIS, "solver": "osqp"}, {}),
}
#: Cases run for fewer steps (a dense OSQP setup at every level of every step is slow).
SHORT = {"pf_osqp": 60}
COLLISION = ("local", "p10", "pf", "pf_defaults")
FAULTS = {
    "local_crossed": ("local", {"contradiction": "crossed", "window_steps": (20, 60)}),
    "p10_crossed": ("p10", {"contradiction": "crossed", "window_steps": (20, 60)}),
    "p10_coupled": ("p10", {"contradiction": "coupled", "window_steps": (20, 60)}),
    "p10_strict_coupled": (
        "p10",
        {"contradiction": "coupled", "window_steps": (20, 60), "priority": "strict"},
    ),
}


def _obstacles(robot):
    from dqcontrol.model.collision import Box, HalfSpace, Sphere

    tool = robot.placement(LBR4P_Q0).translation
    return (
        Sphere(name="ball", position_m=(0.2245, -0.2559, 0.9519), radius_m=0.05),
        Box(name="crate", position_m=tuple(tool + [0.0, 0.25, -0.1]), size_m=(0.1, 0.1, 0.2)),
        HalfSpace(name="table", normal=(0.0, 0.0, 1.0), offset_m=float(tool[2] - 0.3)),
    )


def _collision_limit(robot):
    from dqcontrol.controllers.limits.collision import CollisionLimit
    from dqcontrol.model.collision import CollisionModel

    return CollisionLimit(CollisionModel(robot, _obstacles(robot), self_collision=True))


def _run(ctrl, steps: int) -> np.ndarray:
    """Rows ``[qd_command, s, sigma, fallback]`` of every step of the kinematic loop."""
    q = LBR4P_Q0.copy()
    ctrl.reset(q)
    rows = []
    with single_blas_thread():
        for _ in range(steps):
            res = ctrl.step(q)
            d = res.diagnostics
            rows.append(np.r_[res.qd_command, res.s, res.sigma, float(d.fallback)])
            q = q + PERIOD_S * res.qd_command
            if ctrl.done:
                ctrl.reset(q)
    return np.array(rows)


def digest(steps: int) -> dict[str, np.ndarray]:
    """Every case's commands."""
    from dqcontrol.faults.qp_faults import contradictory

    robot = load_lbr4p()
    out: dict[str, np.ndarray] = {}
    for name, (reg, shared, extra) in CASES.items():
        ctrl = build_controller(reg, robot, Circle(2.0), PERIOD_S, shared=shared, **extra)
        out[name] = _run(ctrl, min(steps, SHORT.get(name, steps)))
        if name in COLLISION:
            ctrl = build_controller(
                reg, robot, Circle(2.0), PERIOD_S, shared=shared,
                extra_limits=(_collision_limit(robot),), **extra,
            )  # fmt: skip
            out[name + "_collision"] = _run(ctrl, steps)
        print(f"{name}: done", flush=True)
    for name, (reg, extra) in FAULTS.items():
        spec = controller_spec(reg)
        kwargs = {**dict(spec.kwargs), **THESIS, **extra}
        ctrl = contradictory(spec.cls)(robot, Circle(2.0), PERIOD_S, **kwargs)
        out[name] = _run(ctrl, steps)
        out[name + "_corrupted"] = np.array([ctrl.qp.corrupted_solves])
        print(f"{name}: done", flush=True)
    return out


def compare(old_path: Path, new_path: Path, rtol: float) -> int:
    old, new = np.load(old_path), np.load(new_path)
    worst = 0.0
    for key in sorted(set(old.files) | set(new.files)):
        if key not in new.files or key not in old.files:
            print(f"{key:28s} only in {'old' if key in old.files else 'new'}")
            continue
        a, b = old[key], new[key]
        if a.shape != b.shape:
            print(f"{key:28s} shape {a.shape} -> {b.shape}")
            worst = np.inf
            continue
        scale = np.maximum(np.maximum(np.abs(a), np.abs(b)), 1e-300)
        rel = float(np.max(np.abs(a - b) / scale)) if a.size else 0.0
        worst = max(worst, rel)
        print(f"{key:28s} largest relative difference {rel:.3g}")
    print(f"largest over all: {worst:.3g}")
    return int(worst > rtol)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, help="write the digest here (.npz)")
    ap.add_argument("--steps", type=int, default=600)
    ap.add_argument("--compare", nargs=2, type=Path, metavar=("OLD", "NEW"))
    ap.add_argument("--rtol", type=float, default=0.0)
    args = ap.parse_args(argv)
    if args.compare:
        return compare(*args.compare, args.rtol)
    if args.out is None:
        ap.error("give --out or --compare")
    np.savez(args.out, **digest(args.steps))
    return 0


if __name__ == "__main__":
    sys.exit(main())
