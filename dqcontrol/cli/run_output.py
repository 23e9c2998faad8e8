"""What ``dqcontrol run`` shows and writes: progress bars, the metrics table, the result
files of its runs and the live viewer kept open after them.

A run here is ``(label, RunResult, anchored trajectory)``, as :mod:`dqcontrol.cli.run_cmd`
collects them. The figures and replays need the ``viz`` extra; without it only the runs are
saved and a note on stderr says what was not written.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

__all__ = [
    "TABLE_LEGEND",
    "collision_report",
    "hold_viewer",
    "loaded_result",
    "metrics_table",
    "progress_bar",
    "progress_callback",
    "show_progress",
    "with_contacts",
    "write_results",
]


# ---------------------------------------------------------------------- progress bars
def show_progress(args: argparse.Namespace) -> bool:
    """Whether to draw progress bars: not with ``--no-progress`` nor ``--short``."""
    return args.progress and not args.short


def progress_bar(label: str, total: float, enabled: bool):
    """A tqdm bar over the phase σ [s]; shown only after one second, and on a terminal."""
    from tqdm import tqdm

    return tqdm(
        total=round(total, 9),
        desc=label,
        unit="s",
        delay=1.0,
        leave=False,
        disable=None if enabled else True,
        bar_format="{desc}: {percentage:3.0f}%|{bar}| σ {n:.2f}/{total:.2f} s "
        "[{elapsed}<{remaining}]",
    )


def progress_callback(bar):
    """The loops' ``on_progress(σ_next, T_tot)`` callback that advances ``bar`` to σ [s]."""
    total = bar.total or 0.0

    def report(sigma_next: float, _duration: float) -> None:
        target = min(float(sigma_next), total)
        if target > bar.n:
            bar.update(target - bar.n)

    return report


# ---------------------------------------------------------------------- the metrics table
_COLUMNS = (
    ("controller", "{:<12}", None),
    ("done", "{:>4}", lambda m: "yes" if m.completed else "NO"),
    ("t_exec", "{:>6}", lambda m: _fmt(m.execution_time_s, "{:.3f}")),
    ("e_mean", "{:>8}", lambda m: _fmt(m.e_mean, "{:.5f}")),
    ("e_max", "{:>8}", lambda m: _fmt(m.e_max, "{:.5f}")),
    ("dev_mm", "{:>6}", lambda m: _fmt(1e3 * m.path_deviation_max_m, "{:.2f}")),
    ("rot_deg", "{:>7}", lambda m: _fmt(math.degrees(m.rotation_error_max_rad), "{:.2f}")),
    ("u_mean", "{:>6}", lambda m: _fmt(m.u_mean_rad_s, "{:.3f}")),
    ("s_mean", "{:>6}", lambda m: _fmt(m.s_mean, "{:.3f}")),
    ("tau_Nm", "{:>6}", lambda m: _fmt(m.torque_peak_nm, "{:.1f}")),
    (
        "viol",
        "{:>7}",
        lambda m: f"{m.position_violations}/{m.velocity_violations}/{m.acceleration_violations}",
    ),
    ("fb", "{:>3}", lambda m: str(m.fallbacks)),
    ("step_ms", "{:>7}", lambda m: _fmt(1e3 * m.step_time_median_s, "{:.2f}")),
)
#: What the columns mean (printed under the table).
TABLE_LEGEND = (
    "t_exec: execution time [s]; e: ‖x_d - x‖; dev_mm: max path deviation [mm]; rot_deg: max "
    "rotation error [deg];\nu_mean [rad/s]; tau_Nm: peak torque; viol: samples outside the "
    "position/velocity/acceleration bounds;\nfb: QP fallbacks; step_ms: median control step [ms]"
)


def _fmt(value: float, spec: str) -> str:
    return "-" if value is None or not math.isfinite(value) else spec.format(value)


def metrics_table(rows: list[tuple[str, object]]) -> str:
    """A plain-text table of ``(label, Metrics)`` rows (violations: position/velocity/accel.)."""
    head = " ".join(fmt.format(name) for name, fmt, _ in _COLUMNS)
    lines = [head, "-" * len(head)]
    for label, metrics in rows:
        cells = [_COLUMNS[0][1].format(label[:12])]
        cells += [fmt.format(get(metrics)) for _, fmt, get in _COLUMNS[1:]]
        lines.append(" ".join(cells))
    return "\n".join(lines)


def with_contacts(runs: list, robot, collision) -> list:
    """``runs`` with each result's contacts measured over its log's samples
    (:func:`~dqcontrol.sim.run_contacts.measure_contacts`), to print and to save; unchanged
    without a collision model, and a run without samples keeps none."""
    import dataclasses

    from dqcontrol.sim.run_contacts import measure_contacts

    if collision is None:
        return runs
    measured = []
    for label, result, traj in runs:
        if len(result.log):
            contacts = measure_contacts(robot, collision, result.log.q, result.log.t_s)
            result = dataclasses.replace(result, contacts=contacts)
        measured.append((label, result, traj))
    return measured


def collision_report(label: str, result) -> str:
    """One line per run: its smallest distance, its contacts with the obstacles and itself
    in the MuJoCo model, and the closest pair (:meth:`RunContacts.summary
    <dqcontrol.runs.contacts.RunContacts.summary>`)."""
    if result.contacts is None:
        return f"{label}: no samples"
    return f"{label}: {result.contacts.summary()}"


# ---------------------------------------------------------------------- the viewer
def hold_viewer(viewer, hold: float | None) -> None:
    """Keep a live viewer open ``hold`` seconds (``None``: until Ctrl-C on a terminal)."""
    if hold is None:
        if not sys.stdin or not sys.stdin.isatty():
            return
        print(f"Meshcat viewer still open at {viewer.url} (replaying); Ctrl-C to quit", flush=True)
        hold = math.inf
    if hold <= 0:
        return
    deadline = time.monotonic() + hold
    try:
        while time.monotonic() < deadline:
            time.sleep(min(0.2, max(deadline - time.monotonic(), 0.0)))
    except KeyboardInterrupt:
        pass


# ---------------------------------------------------------------------- the result files
#: A streamed run up to this many samples is loaded whole (and saved as ``.npz`` too);
#: a longer one is loaded decimated to about this many, for the figures and the replay.
FULL_LOAD_SAMPLES = 100_000


def loaded_result(result):
    """``result`` with its streamed log loaded back from its file (every sample up to
    :data:`FULL_LOAD_SAMPLES`, else every k-th: ``log_stride = k``); unchanged when it has no
    file or the file cannot be read (then its ``log`` stays the last samples)."""
    import dataclasses

    from dqcontrol.errors import DQControlError
    from dqcontrol.runs.storage import load_run

    if result.log_file is None or result.log_stride != 1:
        return result
    try:
        log, record = load_run(result.log_file, max_samples=FULL_LOAD_SAMPLES)
    except (OSError, DQControlError):
        return result
    return dataclasses.replace(result, log=log, log_stride=int(record["stride"]))


def write_results(runs, robot, out: Path, args: argparse.Namespace, name: str) -> list[Path]:
    """Save each run that has samples, its figures and its replay, and the comparison figure
    of two or more, to ``out`` with a progress bar; ``name`` is the robot's label in the
    comparison's title. Without the ``viz`` extra only the runs, and a note on stderr."""
    from tqdm import tqdm

    from dqcontrol.extras import has_extra
    from dqcontrol.runs.storage import save_run

    drawable = [(label, r, traj) for label, r, traj in runs if len(r.log)]
    if not has_extra("viz"):  # the runs alone, and say what is missing
        print(
            "dqcontrol run: figures and replays not written: they need the [viz] extra "
            "(pip install 'dqcontrol[viz]')",
            file=sys.stderr,
        )
        return [path for label, result, _ in drawable for path in save_run(result, out, label)]

    steps = 3 * len(drawable) + (len(drawable) >= 2)
    written: list[Path] = []
    with tqdm(
        total=steps,
        desc="writing results",
        unit="file",
        delay=1.0,
        leave=False,
        disable=None if show_progress(args) else True,
    ) as bar:
        for label, result, traj in drawable:
            written += _write_run(bar, label, result, traj, robot, out, args)
        if len(drawable) >= 2:
            written.append(_write_comparison(drawable, out, args, name))
            bar.update()
    return written


def _figure_settings(args: argparse.Namespace) -> tuple[str, float, float]:
    """The figures' format and dpi and the replays' frame rate: smaller with ``--short``."""
    fmt = "svg" if args.svg else "png"
    dpi = 60.0 if args.short else 110.0
    fps = 10.0 if args.short else 30.0
    return fmt, dpi, fps


def _write_run(bar, label: str, result, traj, robot, out: Path, args) -> list[Path]:
    """Save one run (``.npz`` + ``.json``), its figures and its HTML replay, advancing
    ``bar`` after each of the three."""
    from dqcontrol.runs.storage import save_run
    from dqcontrol.viz.figures import plot_run
    from dqcontrol.viz.meshcat_viewer import export_replay_html

    fmt, dpi, fps = _figure_settings(args)
    written: list[Path] = []
    written += save_run(result, out, label)
    bar.update()
    written += plot_run(result.log, out, name=label, trajectory=traj, fmt=fmt, dpi=dpi)
    bar.update()
    html = out / f"{label}_replay.html"
    points = traj.path_positions(1000)
    collision = getattr(args, "_collision", None)
    written.append(
        export_replay_html(
            robot,
            result.log,
            html,
            path_points=points,
            fps=fps,
            speed=args.speed,
            obstacles=collision.obstacles if collision is not None else (),
        )
    )
    bar.update()
    return written


def _write_comparison(drawable, out: Path, args: argparse.Namespace, name: str) -> Path:
    """The figure comparing the runs of ``drawable``, against the last one's trajectory."""
    from dqcontrol.viz.figures import plot_comparison

    fmt, dpi, _ = _figure_settings(args)
    title = (
        f"{name}, {args.trajectory}, T_tot = {args.duration:g} s, T = {args.period:g} s, "
        f"{args.simulator}"
    )
    logs = {label: r.log for label, r, _ in drawable}
    return plot_comparison(
        logs,
        out / f"comparison.{fmt}",
        trajectory=drawable[-1][2],
        dpi=dpi,
        title=title,
    )
