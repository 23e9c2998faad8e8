"""Figures of docs/faults.md (``python -m dqcontrol.faults.figures --out docs/img``).

- ``faults_unreachable.png``: the circle of radius 0.4 m, partly outside the LBR4p's
  workspace, in MuJoCo — the tool's path seen from above, the time scaling ``s``, the path
  deviation and the largest joint speed, for the QP controllers and the two without
  scaling;
- ``faults_limits.png``: how far the most exposed joint goes beyond its limit when the
  arm starts within a degree of its limits, with exact, noisy and delayed measurements, and
  with the controller unaware of the fault and with the delay compensated
  (:mod:`dqcontrol.faults.analysis`).

With ``--mitigations`` it also prints the what-if table of
:func:`~dqcontrol.faults.analysis.mitigation_table` (Markdown).
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from dqcontrol.dq.algebra import translation
from dqcontrol.experiments.runner import lbr4p
from dqcontrol.extras import require
from dqcontrol.faults.analysis import (
    compensate_delay,
    mitigation_table,
    position_margin,
    render_mitigations,
)
from dqcontrol.faults.campaign import PERIOD_S, CaseSpec, run_case
from dqcontrol.faults.scenarios import CONTROLLERS, TRAJECTORIES, fault_by_name

__all__ = ["limits_figure", "main", "unreachable_figure"]

_COLORS = {
    "local": "tab:blue",
    "predictive_p6": "tab:green",
    "predictive_noscale_p6": "tab:orange",
    "proportional": "tab:red",
}
_LABELS = {
    "local": "local",
    "predictive_p6": "predictive p = 6",
    "predictive_noscale_p6": "predictive p = 6, no scaling",
    "proportional": "proportional",
}


def _case(fault: str, traj: str, controller: str, simulator: str = "mujoco", hook=None, aware=True):
    spec = CaseSpec(
        CONTROLLERS[controller],
        TRAJECTORIES[traj],
        replace(fault_by_name(fault), compensated=aware),
        simulator,
        TRAJECTORIES[traj].duration_s,
    )
    return run_case(spec, keep_log=True, hook=hook)


def _pyplot() -> Any:
    """``matplotlib.pyplot`` with the Agg backend (files only, no window)."""
    matplotlib = require("matplotlib", extra="viz", purpose="the fault campaign's figures")
    matplotlib.use("Agg")
    return require("matplotlib.pyplot", extra="viz", purpose="the fault campaign's figures")


def unreachable_figure(path: Path) -> Path:
    """``faults_unreachable.png`` (see the module docstring)."""
    plt = _pyplot()

    robot = lbr4p()
    fig, axes = plt.subplots(2, 2, figsize=(9.0, 6.6))
    (ax_top, ax_s), (ax_dev, ax_qd) = axes
    path_drawn = False
    for name, color in _COLORS.items():
        r = _case("unreachable", "circle", name)
        log, traj = r.log, r.anchored_trajectory
        t = log.t_s
        if not path_drawn:
            pts = traj.path_positions(400)
            ax_top.plot(pts[:, 0], pts[:, 1], "k--", lw=1.0, label="path (R = 0.4 m)")
            ax_top.plot(pts[0, 0], pts[0, 1], "ko", ms=4)
            path_drawn = True
        tool = translation(robot.poses(r.true_q))
        label = _LABELS[name]
        ax_top.plot(tool[:, 0], tool[:, 1], color=color, lw=1.4, label=label)
        ax_s.plot(t, log.s, color=color, lw=1.2, label=label)
        ax_dev.semilogy(t, np.maximum(1000.0 * r.path_dev, 1e-3), color=color, lw=1.2)
        ax_qd.plot(t, np.abs(log.qd_command).max(axis=1), color=color, lw=1.0)
    ax_top.set(xlabel="x [m]", ylabel="y [m]", title="tool seen from above (MuJoCo)")
    ax_top.set_aspect("equal", adjustable="datalim")
    ax_top.legend(fontsize=7, loc="lower left")
    ax_s.set(xlabel="t [s]", ylabel="s", title="time scaling s", ylim=(-0.05, 1.05))
    ax_dev.set(xlabel="t [s]", ylabel="[mm]", title="path deviation (true state)")
    ax_qd.set(xlabel="t [s]", ylabel="[rad/s]", title="largest commanded joint speed")
    for ax in (ax_s, ax_dev, ax_qd):
        ax.grid(True, alpha=0.3)
    fig.suptitle("Unreachable path: circle R = 0.4 m, T_tot = 2 s, LBR4p", fontsize=11)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def _excess_mrad(r) -> tuple[np.ndarray, np.ndarray]:
    """Time [s] and the largest signed distance beyond a joint limit [mrad] (> 0: beyond)."""
    lim = lbr4p().limits
    q = r.true_q
    excess = np.maximum(q - lim.q_max, lim.q_min - q).max(axis=1)
    return PERIOD_S * np.arange(q.shape[0]), 1000.0 * excess


#: The runs of ``faults_limits.png``: label, fault, simulator, hook on the controller's
#: configuration (:func:`~dqcontrol.faults.campaign.run_case`), colour and line style.
_LIMITS_RUNS = (
    (
        "MuJoCo, exact measurements, no margin",
        "near_limits",
        "mujoco",
        lambda c: position_margin(c, 0.0),
        "tab:blue",
        "-",
    ),
    (
        "MuJoCo, noise 2 mrad, margin 5 mrad",
        "near_limits_noise",
        "mujoco",
        None,
        "tab:purple",
        "-",
    ),
    ("MuJoCo, delay 2 T, unaware", "near_limits_delay_2", "mujoco", None, "tab:red", "-"),
    (
        "kinematic, delay 2 T, unaware",
        "near_limits_delay_2",
        "kinematic",
        None,
        "tab:orange",
        "-",
    ),
    (
        "MuJoCo, delay 2 T, compensated, 5 mrad margin",
        "near_limits_delay_2",
        "mujoco",
        lambda c: compensate_delay(c, 2),
        "tab:green",
        "--",
    ),
    (
        "kinematic, delay 2 T, compensated",
        "near_limits_delay_2",
        "kinematic",
        lambda c: compensate_delay(c, 2),
        "tab:olive",
        "--",
    ),
)


def limits_figure(path: Path) -> Path:
    """``faults_limits.png`` (see the module docstring)."""
    plt = _pyplot()

    fig, ax = plt.subplots(figsize=(8.0, 5.0))
    for label, fault, sim, hook, color, style in _LIMITS_RUNS:
        r = _case(fault, "circle", "local", sim, hook, aware=False)
        t, e = _excess_mrad(r)
        ax.plot(t, e, style, color=color, lw=1.3, label=f"{label}: max {max(e.max(), 0):.2f}")
    ax.axhline(0.0, color="k", lw=0.8)
    ax.set_yscale("symlog", linthresh=0.1)
    ax.set(
        xlabel="t [s]",
        ylabel="beyond the limit [mrad]  (< 0: inside)",
        title="Start 0.8° from every joint limit, circle, local QP controller: "
        "the most exposed joint",
    )
    ax.title.set_fontsize(10)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.14), ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def main(argv: list[str] | None = None) -> int:
    """Write the figures (and print the mitigation table with ``--mitigations``)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("docs/img"))
    parser.add_argument("--mitigations", action="store_true")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    for path in (
        unreachable_figure(args.out / "faults_unreachable.png"),
        limits_figure(args.out / "faults_limits.png"),
    ):
        print(f"wrote {path} ({path.stat().st_size // 1024} kB)")
    if args.mitigations:
        print(render_mitigations(mitigation_table("mujoco")))
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
