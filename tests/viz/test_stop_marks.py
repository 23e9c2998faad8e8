"""The stop in the figures and in ``dqcontrol view`` (dqcontrol/viz/stop_marks.py)."""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.figure import Figure

from dqcontrol.controllers import LocalController
from dqcontrol.model import LBR4P_Q0
from dqcontrol.runs.log import RunLog
from dqcontrol.sim import KinematicDriver, run_loop
from dqcontrol.trajectories import Circle
from dqcontrol.viz.figures import plot_run
from dqcontrol.viz.stop_marks import mark_stop_on_path, shade_stop, stop_summary

T = 0.05


@pytest.fixture(scope="module")
def stopped(lbr4p):
    ctrl = LocalController(lbr4p, Circle(1.0), T)

    def request(_k, _driver, result) -> None:
        if result.sigma_next >= 0.5 and not ctrl.stopping:
            ctrl.request_stop()

    return run_loop(ctrl, KinematicDriver(lbr4p, T), q0=LBR4P_Q0, on_sample=request).log


def test_the_stop_is_shaded_over_its_samples(stopped):
    ax = Figure().add_subplot()
    shade_stop(ax, stopped, stopped.t_s)
    first = int(np.argmax(stopped.stopping))
    (span,) = ax.patches
    bbox = span.get_bbox()  # data x, axes y
    assert bbox.x0 == pytest.approx(stopped.t_s[first])
    assert bbox.x1 == pytest.approx(stopped.t_s[-1])
    assert ax.get_legend_handles_labels()[1] == ["stop"]


def test_a_run_without_a_stop_has_no_marks(stopped):
    arrays = stopped.arrays()
    arrays["stopping"] = np.zeros(len(stopped), dtype=bool)
    plain = RunLog.from_arrays(arrays, stopped.meta)
    ax = Figure().add_subplot()
    shade_stop(ax, plain, plain.t_s)
    mark_stop_on_path(ax, plain, np.zeros((len(plain), 2)))
    assert not ax.patches and not ax.lines and stop_summary(plain) == ""


def test_the_summary_names_the_stop(stopped):
    text = stop_summary(stopped)
    count = int(stopped.stopping.sum())
    assert text.startswith(f"stop (request): {count} samples ({count * T:.3f} s)")


def test_the_figures_are_written_with_the_stop(stopped, tmp_path):
    paths = plot_run(stopped, tmp_path, figures=("path_2d", "joint_velocities", "scaling"))
    assert [p.name for p in paths] == [
        "run_path_2d.png", "run_joint_velocities.png", "run_scaling.png",
    ]  # fmt: skip


class _Flags:
    """A log stand-in: only its ``stopping`` flags."""

    def __init__(self, flags: list[int]) -> None:
        self.stopping = np.array(flags, dtype=bool)


def test_every_run_of_flagged_samples_is_one_span():
    from dqcontrol.viz.stop_marks import _spans

    assert _spans(np.array([0, 1, 1, 0, 1, 0, 0, 1], dtype=bool)) == [(1, 2), (4, 4), (7, 7)]
    assert _spans(np.zeros(4, dtype=bool)) == []


def test_each_span_runs_to_the_sample_after_it_and_is_labelled_once():
    ax = Figure().add_subplot()
    x = np.arange(8) * 0.5
    shade_stop(ax, _Flags([0, 1, 1, 0, 1, 0, 0, 1]), x)
    spans = [(p.get_bbox().x0, p.get_bbox().x1) for p in ax.patches]
    assert spans == [(0.5, 1.5), (2.0, 2.5), (3.5, 3.5)]  # the last one ends at the last x
    assert ax.get_legend_handles_labels()[1] == ["stop"]
    quiet = Figure().add_subplot()
    shade_stop(quiet, _Flags([1, 0]), x[:2], label=False)
    assert quiet.get_legend_handles_labels()[1] == []


def test_the_stop_is_marked_where_it_began_on_the_path():
    ax = Figure().add_subplot()
    points = np.array([[0.0, 0.0], [1.0, 2.0], [3.0, 4.0]])
    mark_stop_on_path(ax, _Flags([0, 1, 1]), points)
    (marker,) = ax.lines
    assert (marker.get_xdata()[0], marker.get_ydata()[0]) == (1.0, 2.0)
