"""Computed torque vs velocity servo on Table 1's hard cases, with and without a payload the
model does not know: the table and figure of docs/drivers.md.

    python docs/drivers_comparison.py            # prints the table, writes the figure
    python docs/drivers_comparison.py --short    # one case, no figure (a smoke test)
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from dqcontrol.experiments.table1 import Table1Case, Table1Settings
from dqcontrol.sim import MujocoDriver, PayloadDriver, run_loop

CASES = (("circle", 1.0), ("sinusoid", 2.0))
CONTROLLERS = ("local", "p10", "pf")
DRIVES = (("velocity", 0.0), ("torque", 0.0), ("velocity", 3.0), ("torque", 3.0))
FIGURE = Path(__file__).resolve().parent / "img" / "drivers_torque_vs_servo.png"


def run(trajectory: str, duration: float, controller: str, motor: str, payload: float):
    """One Table 1 case (its settings, MuJoCo) with the given joint drive and payload."""
    settings = Table1Settings()
    case = Table1Case(trajectory, duration, controller)
    robot, ctrl = case.build(settings)
    driver = MujocoDriver(robot, settings.period_s, motor=motor)
    if payload > 0.0:
        driver = PayloadDriver(driver, payload)
    result = run_loop(ctrl, driver, q0=settings.start_configuration(), brake=False)
    log = result.log
    err = log.qd_measured[1:] - log.qd_command[:-1]
    return {
        "case": f"{trajectory} {duration:g} s",
        "controller": controller,
        "drive": "computed torque" if motor == "torque" else "velocity servo",
        "payload_kg": payload,
        "completed": result.metrics.completed,
        "qd_err_rms": float(np.sqrt(np.mean(err**2))),
        "qd_err_max": float(np.abs(err).max()),
        "e_mean": result.metrics.e_mean,
        "dev_max_mm": 1e3 * result.metrics.path_deviation_max_m,
        "tau_ratio": float(np.max(log.torque_peak / driver.simulation.torque_limit)),
        "log": log,
    }


def table(rows) -> str:
    head = (
        "| case | controller | drive | payload [kg] | done | qd error RMS / max [rad/s] "
        "| e_mean | max deviation [mm] | peak torque / limit |"
    )
    lines = [head, "|" + "---|" * 9]
    for r in rows:
        lines.append(
            f"| {r['case']} | {r['controller']} | {r['drive']} | {r['payload_kg']:g} | "
            f"{'yes' if r['completed'] else 'NO'} | {r['qd_err_rms']:.1e} / "
            f"{r['qd_err_max']:.1e} | {r['e_mean']:.4f} | {r['dev_max_mm']:.1f} | "
            f"{r['tau_ratio']:.2f} |"
        )
    return "\n".join(lines)


def figure(rows, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    pick = [r for r in rows if r["case"] == "circle 1 s" and r["controller"] == "local"]
    fig, axes = plt.subplots(2, 1, figsize=(7.5, 5.5), sharex=True)
    for r in pick:
        log = r["log"]
        style = "-" if r["drive"] == "computed torque" else "--"
        label = f"{r['drive']}, payload {r['payload_kg']:g} kg"
        err = np.linalg.norm(log.qd_measured[1:] - log.qd_command[:-1], axis=1)
        axes[0].semilogy(log.t_s[1:], np.maximum(err, 1e-6), style, label=label)
        axes[1].plot(log.t_s, np.max(np.abs(log.torque_peak) / _limit(), axis=1), style)
    axes[0].set_ylabel("‖qd(t_k+1) − u_k‖ [rad/s]")
    axes[1].set_ylabel("peak |τ| / limit (worst joint)")
    axes[1].set_xlabel("t [s]")
    axes[0].legend(fontsize=8)
    axes[0].set_title("LBR4p, circle T_tot = 1 s, local controller, T = 0.05 s (MuJoCo)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _limit() -> np.ndarray:
    from dqcontrol.experiments.runner import lbr4p

    return np.asarray(lbr4p().limits.effort_max, dtype=float)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--short", action="store_true", help="one case, no figure")
    args = parser.parse_args(argv)
    cases = CASES[:1] if args.short else CASES
    controllers = CONTROLLERS[:1] if args.short else CONTROLLERS
    drives = DRIVES[:2] if args.short else DRIVES
    rows = [
        run(traj, duration, ctrl, motor, payload)
        for traj, duration in cases
        for ctrl in controllers
        for motor, payload in drives
    ]
    print(table(rows))
    if not args.short:
        figure(rows, FIGURE)
        print(f"wrote {FIGURE}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
