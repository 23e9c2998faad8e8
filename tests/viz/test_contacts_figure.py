"""The contacts figure of a run (dqcontrol/viz/contacts_figure.py), drawn from hand-made
contacts: the plotted lines are the columns (distance in mm), the title's counts and
pair, the errors on missing or mismatched columns, and the file written; and drawn from the
contacts measured along a run of the LBR4p into a plane."""

from __future__ import annotations

import numpy as np
import pytest
from runs.test_contacts import _PLANE, _log

from dqcontrol.errors import ParameterError
from dqcontrol.model import LBR4P_Q0
from dqcontrol.model.collision import CollisionModel
from dqcontrol.runs.contacts import ContactKind, RunContacts
from dqcontrol.sim.run_contacts import measure_contacts
from dqcontrol.viz.contacts_figure import contacts_figure, plot_contacts

T_S = np.arange(5) * 0.05


def _contacts(per_sample=True, obstacles=("table",), closest=0.0123) -> RunContacts:
    columns = {
        "contacts_closest_m": np.array([0.05, 0.03, 0.0123, -0.002, 0.01]),
        "contacts_obstacle": np.array([0, 0, 0, 2, 0]),
        "contacts_self": np.array([0, 1, 0, 0, 0]),
        "contacts_depth_m": np.array([0.0, 0.001, 0.0, 0.002, 0.0]),
    }
    return RunContacts(
        obstacles=obstacles, self_collision=True, samples=5,
        obstacle=ContactKind(2, 1, 0.002), self_contact=ContactKind(1, 1, 0.001),
        closest_m=closest, closest_pair=("link_5_0", "table") if closest is not None else None,
        closest_links=("link_5", "table") if closest is not None else None,
        closest_t_s=0.1 if closest is not None else None,
        per_sample=columns if per_sample else None,
    )  # fmt: skip


def test_the_lines_are_the_columns_and_the_title_names_the_pair():
    contacts = _contacts()
    fig = contacts_figure(contacts, T_S, safety_distance_m=0.02)
    ax_d, ax_c = fig.axes
    distance, safety, zero = ax_d.lines
    np.testing.assert_allclose(distance.get_xdata(), T_S)
    np.testing.assert_allclose(distance.get_ydata(), [50.0, 30.0, 12.3, -2.0, 10.0])
    assert safety.get_ydata()[0] == pytest.approx(20.0) and zero.get_ydata()[0] == 0.0
    np.testing.assert_array_equal(ax_c.lines[0].get_ydata(), [0, 0, 0, 2, 0])
    np.testing.assert_array_equal(ax_c.lines[1].get_ydata(), [0, 1, 0, 0, 0])
    assert ax_d.get_title() == (
        "contacts: robot-obstacle 2, self 1, deepest 2.0 mm\nclosest 12.3 mm: link_5–table"
    )
    assert ax_c.get_xlabel() == "t [s]" and ax_d.get_ylabel() == "distance [mm]"


def test_without_safety_distance_obstacles_or_pair():
    fig = contacts_figure(_contacts(obstacles=(), closest=None), T_S)
    ax_d, _ = fig.axes
    assert len(ax_d.lines) == 2  # the distance and the zero line only
    assert ax_d.get_title() == ("contacts: no obstacles, self 1, deepest 2.0 mm\nno collision pair")


def test_columns_missing_or_of_another_length_are_refused():
    with pytest.raises(ParameterError, match="no per-sample columns"):
        contacts_figure(_contacts(per_sample=False), T_S)
    with pytest.raises(ParameterError, match=r"contacts per sample \(5\) do not match the run's 4"):
        contacts_figure(_contacts(), T_S[:4])


def test_the_figure_is_written_in_the_suffixs_format(tmp_path):
    png = plot_contacts(_contacts(), T_S, tmp_path / "c.png", dpi=40)
    assert png == tmp_path / "c.png" and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    svg = plot_contacts(_contacts(), T_S, tmp_path / "c.svg", safety_distance_m=0.02)
    assert "<svg" in svg.read_text()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.png", "c.svg"]  # no leftovers


def test_the_figure_draws_the_columns_and_names_the_pair(lbr4p):
    collision = CollisionModel(lbr4p, [_PLANE], self_collision=False)
    qs = LBR4P_Q0 + np.linspace(0.0, 0.2, 5)[:, None]
    log = _log(qs)
    contacts = measure_contacts(lbr4p, collision, log.q, log.t_s)
    fig = contacts_figure(contacts, log.t_s, safety_distance_m=0.02)
    ax_d, ax_c = fig.axes
    np.testing.assert_allclose(
        ax_d.lines[0].get_ydata(), 1e3 * contacts.per_sample["contacts_closest_m"]
    )
    obstacle = contacts.per_sample["contacts_obstacle"]
    np.testing.assert_array_equal(ax_c.lines[0].get_ydata(), obstacle)
    title = ax_d.get_title()
    assert f"robot-obstacle {contacts.obstacle.count}" in title
    assert "–".join(contacts.closest_links) in title
