"""The stop in a run's figures: its samples (flagged ``stopping`` in the log) shaded on
every time axis, and its first point marked on the path."""

from __future__ import annotations

import numpy as np

from dqcontrol.runs.log import RunLog

__all__ = ["mark_stop_on_path", "shade_stop", "stop_summary"]

#: The shading of the stop's span.
STOP_STYLE = {"color": "C3", "alpha": 0.12, "linewidth": 0}


def _spans(flags: np.ndarray) -> list[tuple[int, int]]:
    """``(first, last)`` sample of every run of consecutive flagged samples."""
    edges = np.diff(np.concatenate(([0], flags.astype(np.int8), [0])))
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1, strict=True))


def shade_stop(ax, log: RunLog, x: np.ndarray, label: bool = True) -> None:
    """Shade the stop's samples on ``ax`` over the abscissa ``x`` (one value a sample;
    a span runs to the sample after its last, where there is one)."""
    for k, (first, last) in enumerate(_spans(np.asarray(log.stopping, dtype=bool))):
        end = x[min(last + 1, len(x) - 1)]
        ax.axvspan(x[first], end, label="stop" if label and k == 0 else None, **STOP_STYLE)


def mark_stop_on_path(ax, log: RunLog, points_2d: np.ndarray) -> None:
    """A marker where the stop began on the plotted path (``points_2d``, one a sample)."""
    flags = np.asarray(log.stopping, dtype=bool)
    if flags.any():
        first = int(np.argmax(flags))
        ax.plot(*points_2d[first, :2], "s", color="C3", markersize=5, label="stop")


def stop_summary(log: RunLog) -> str:
    """One line on the stop for the command line (``""``: the run has none)."""
    flags = np.asarray(log.stopping, dtype=bool)
    if not flags.any():
        return ""
    stop = log.meta.get("stop", {}) if isinstance(log.meta.get("stop"), dict) else {}
    period = float(log.meta.get("period_s", 0.0) or 0.0)
    count = int(flags.sum())
    text = (
        f"stop ({stop.get('reason', '?')}): {count} samples ({count * period:.3f} s), "
        f"from σ = {float(log.sigma[int(np.argmax(flags))]):.4f} s"
    )
    if stop.get("ramp"):
        text += f"; {stop['ramp']}"
    return text
