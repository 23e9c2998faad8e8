"""``dqcontrol view``: replay a saved run in the browser, and/or regenerate its replay HTML
and figures."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from dqcontrol.cli.common import NO_BARS_HELP, add_out_option, add_progress_option

__all__ = ["DISPLAY_SAMPLES", "register"]

#: A longer streamed run is decimated to about this many samples for display.
DISPLAY_SAMPLES = 100_000

_DESCRIPTION = """\
Replay a run saved by 'dqcontrol run' (its .npz, .json or streamed .mcap log): by default
in the live Meshcat viewer (a local server; the URL is printed), where the browser plays
the motion with the reference path, the end-effector trace and the target frame, and loops
it. With --html and --figures it (re)writes the self-contained HTML replay and the figures
of the run, without a server unless --viewer is also given. A streamed log cut short (the
process was killed) is read up to its last complete chunk and reported as such; a long run
is decimated for display."""

_EPILOG = """\
examples:
  dqcontrol view results/lbr4p_circle_T2s_mujoco/p10.npz
  dqcontrol view results/lbr4p_circle_T2s_mujoco/p10.npz --speed 0.25
  dqcontrol view RUN.npz --no-viewer --html --figures --out /tmp/replay"""


def register(subparsers) -> None:
    """Add the ``view`` subcommand."""
    p = subparsers.add_parser(
        "view",
        help="replay a saved run in the browser (and/or rewrite its HTML replay and figures)",
        description=_DESCRIPTION,
        epilog=_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("run", metavar="RUN", help="a saved run: its .npz, .json, .mcap or their stem")
    p.add_argument(
        "--viewer",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="replay in the live browser viewer (default: on, unless --html or --figures is given)",
    )
    p.add_argument("--html", action="store_true", help="write the self-contained HTML replay")
    p.add_argument("--figures", action="store_true", help="write the run's figures")
    p.add_argument("--svg", action="store_true", help="figures as SVG instead of PNG")
    add_out_option(p, None, "folder for --html and --figures (default: the run's own folder)")
    add_progress_option(p, NO_BARS_HELP)
    p.add_argument(
        "--speed",
        type=_positive_speed,
        default=1.0,
        help="replay speed (1 = real time, default)",
    )
    p.add_argument(
        "--hold",
        type=float,
        metavar="SECONDS",
        help="keep the live viewer open this long (default: until Ctrl-C when run from a "
        "terminal, else not at all)",
    )
    p.set_defaults(func=_main, _parser=p)


def _positive_speed(text: str) -> float:
    """The argparse type of ``--speed``: a finite number > 0."""
    from dqcontrol.cli.run_options import positive_float

    return positive_float("x real time")(text)


def _main(args: argparse.Namespace) -> int:
    """Replay the saved run in the live viewer and/or write its figures and HTML replay.

    Returns:
        The exit code, 0; bad options exit with 2, an unreadable run raises
        :class:`~dqcontrol.errors.ParameterError`.
    """
    json_path, name, viewer_on = _check_options(args)

    from dqcontrol.cli.robot_options import robot_from_meta
    from dqcontrol.cli.run_cmd import trajectory_from_meta
    from dqcontrol.runs.contacts import contacts_text, loaded_contacts
    from dqcontrol.sim.bridge import run_origin
    from dqcontrol.viz.stop_marks import stop_summary

    log, record = _load_log(json_path)
    meta = log.meta
    print(f"run {name}: states from {run_origin(meta)}", flush=True)
    print(contacts_text(record), flush=True)
    stop = stop_summary(log)
    if stop:
        print(stop, flush=True)
    trajectory = trajectory_from_meta(meta, log)
    path_points = trajectory.path_positions(1000) if trajectory is not None else None
    out = Path(args.out) if args.out else json_path.parent
    robot = None
    if args.html or viewer_on:
        robot = robot_from_meta(meta)
    written = _write_files(args, log, robot, trajectory, path_points, out, name)
    written += _write_contacts(args, log, loaded_contacts(record), out, name)
    if written:
        print(f"wrote {len(written)} file{'s' if len(written) != 1 else ''} to {out}/")
    if viewer_on:
        assert robot is not None, "built above for the viewer"
        _replay(args, log, robot, path_points, name)
    return 0


def _check_options(args: argparse.Namespace) -> tuple[Path, str, bool]:
    """The saved run's ``.json``, its name, and whether to open the live viewer; parser
    error (exit 2) for a missing run, a negative ``--hold`` or nothing to do."""
    from dqcontrol.runs.storage import run_file, run_paths

    parser = args._parser
    json_path = run_file(args.run)
    if not json_path.is_file():
        expected, _npz, mcap_path = run_paths(args.run)
        parser.error(f"RUN: no saved run at {args.run!r} (expected {expected} or {mcap_path})")
    if args.hold is not None and not (args.hold >= 0):
        parser.error(f"--hold must be >= 0 seconds, got {args.hold}")
    viewer_on = args.viewer if args.viewer is not None else not (args.html or args.figures)
    if not (viewer_on or args.html or args.figures):
        parser.error("nothing to do: give --viewer, --html or --figures")
    return json_path, json_path.stem, viewer_on


def _load_log(json_path: Path):
    """The log of the saved run (decimated to :data:`DISPLAY_SAMPLES` if longer) and its
    record, a line on stderr if it was cut short;
    :class:`~dqcontrol.errors.ParameterError` if it cannot be read or has no samples."""
    from dqcontrol.errors import ParameterError
    from dqcontrol.runs.storage import load_run

    try:
        log, record = load_run(json_path, max_samples=DISPLAY_SAMPLES)
    except (OSError, ValueError) as exc:
        raise ParameterError(f"cannot read the run {json_path}: {exc}") from None
    if record.get("complete") is False:
        print(f"dqcontrol view: {json_path.name} is incomplete: {record['note']}", file=sys.stderr)
    if record.get("stride", 1) > 1:
        print(f"{record['samples']} samples, every {record['stride']}th shown", flush=True)
    if len(log) == 0:
        raise ParameterError(f"the run {json_path} has no samples")
    return log, record


def _write_files(args, log, robot, trajectory, path_points, out: Path, name: str) -> list[Path]:
    """Write the run's figures (``--figures``) and its HTML replay (``--html``) to ``out``."""
    written: list[Path] = []
    if args.figures:
        from dqcontrol.viz.figures import plot_run

        fmt = "svg" if args.svg else "png"
        written += plot_run(log, out, name=name, trajectory=trajectory, fmt=fmt)
    if args.html:
        from dqcontrol.viz.meshcat_viewer import export_replay_html

        assert robot is not None, "built by the caller for --html"
        written.append(
            export_replay_html(
                robot, log, out / f"{name}_replay.html", path_points=path_points, speed=args.speed
            )
        )
    return written


def _write_contacts(args, log, contacts, out: Path, name: str) -> list[Path]:
    """With ``--figures``, the contacts figure of a run saved with contacts per sample."""
    if not args.figures or contacts is None or contacts.per_sample is None:
        return []
    if len(contacts.per_sample["contacts_closest_m"]) != len(log):
        return []
    from dqcontrol.viz.contacts_figure import plot_contacts

    fmt = "svg" if args.svg else "png"
    safety = log.meta.get("safety_distance_m")
    return [
        plot_contacts(
            contacts,
            log.t_s,
            out / f"{name}_contacts.{fmt}",
            safety_distance_m=float(safety) if safety is not None else None,
        )
    ]


def _replay(args: argparse.Namespace, log, robot, path_points, name: str) -> None:
    """Play the run in the live viewer, looping, and keep it open ``--hold``."""
    from dqcontrol.cli.run_output import hold_viewer
    from dqcontrol.dq.algebra import translation
    from dqcontrol.viz.meshcat_viewer import MeshcatViewer

    meta = log.meta
    with MeshcatViewer(robot, q=log.q[0]) as viewer:
        points = path_points if path_points is not None else translation(log.target)
        viewer.show_path(points)
        viewer.frame_scene(points)
        viewer.set_animation(log, speed=args.speed)
        label = meta.get("label") or meta.get("controller") or name
        print(f"replaying {label} ({len(log)} samples, {log.t_s[-1]:.2f} s)", flush=True)
        hold = args.hold
        if hold is None and not (sys.stdin and sys.stdin.isatty()):
            print("not waiting (stdin is not a terminal); use --hold SECONDS to keep it open")
        hold_viewer(viewer, hold)
