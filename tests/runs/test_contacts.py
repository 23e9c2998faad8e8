"""The contacts of a run in its saved files (dqcontrol/runs/contacts.py, docs/run_logs.md):
measured once, printed and saved by ``dqcontrol run``, loaded back equal; a run saved without
them still loads and says so."""

from __future__ import annotations

import contextlib
import io
import json
import re
from types import SimpleNamespace

import numpy as np
import pytest

from dqcontrol import load_lbr4p
from dqcontrol.cli import main
from dqcontrol.model import LBR4P_Q0
from dqcontrol.model.collision import CollisionModel, HalfSpace, parse_obstacle
from dqcontrol.runs.contacts import CONTACT_COLUMNS, contacts_text, loaded_contacts
from dqcontrol.runs.log import RunLog
from dqcontrol.runs.storage import load_run, save_run
from dqcontrol.sim.mjcf_builder import replay_contacts
from dqcontrol.sim.run_contacts import measure_contacts

#: A ball on the circle's path at σ = 1 s (the circle at 2 s from the LBR4p's start posture).
BALL = "sphere:0.4865,-0.3922,0.7006,0.03"


#: The solid below z = 0.6 m: it cuts the LBR4p's upper arm at its start posture.
_PLANE = HalfSpace(name="table", normal=(0.0, 0.0, 1.0), offset_m=0.6)


@pytest.fixture(scope="module")
def lbr4p():
    return load_lbr4p()


@pytest.fixture(scope="module")
def blocked_run(tmp_path_factory):
    """``dqcontrol run`` with the ball on the path, kinematic loop, T = 50 ms: its printed
    output and its folder (figures and replay not drawn: not under test here)."""
    import dqcontrol.viz.figures as figures
    import dqcontrol.viz.meshcat_viewer as viewer

    out = tmp_path_factory.mktemp("results")
    printed = io.StringIO()
    with pytest.MonkeyPatch.context() as mp, contextlib.redirect_stdout(printed):
        mp.setattr(figures, "plot_run", lambda *a, **k: [])
        mp.setattr(viewer, "export_replay_html", lambda *a, path_points, **k: a[2])
        code = main(
            ["run", "--simulator", "kinematic", "--controllers", "pf", "--period", "0.05",
             "--duration", "2", "--obstacle", BALL, "--short", "--out", str(out)]
        )  # fmt: skip
    assert code == 1  # blocked by the ball
    return printed.getvalue(), out / "lbr4p_circle_T2s_kinematic"


def _log(qs: np.ndarray, period_s: float = 0.01) -> RunLog:
    """A run log whose samples are the joint positions ``qs`` (the rest zeros)."""
    count, n = qs.shape
    zeros, rows = np.zeros(count), np.zeros((count, n))
    return RunLog(
        t_s=period_s * np.arange(count), sigma=zeros, s=zeros, q=qs, qd_measured=rows,
        qd_command=rows, torque=rows, torque_peak=rows, pose=np.zeros((count, 8)),
        target=np.zeros((count, 8)), solver_status=np.full(count, "solved", dtype="U32"),
        iterations=np.zeros(count, dtype=int), solve_time_s=zeros, step_time_s=zeros,
        fallback=zeros.astype(bool), relaxed=zeros.astype(bool), saturated=zeros.astype(bool),
    )  # fmt: skip


def _result(log: RunLog, contacts=None):
    return SimpleNamespace(
        log=log, metrics=SimpleNamespace(as_dict=dict), interrupted=False, note="",
        contacts=contacts,
    )  # fmt: skip


def test_the_saved_contacts_are_those_printed_and_measured(blocked_run, lbr4p):
    printed, folder = blocked_run
    log, record = load_run(folder / "pf.json")
    contacts = loaded_contacts(record)
    assert contacts is not None and contacts.obstacles == ("obstacle1",)
    assert not contacts.self_collision and contacts.samples == len(log)
    line = re.search(r"pf: (min distance .*)$", printed, re.MULTILINE)
    assert line is not None, printed
    assert line.group(1) == contacts.summary()
    # recomputed independently from the loaded joint positions
    ball = parse_obstacle(BALL, name="obstacle1")
    collision = CollisionModel(lbr4p, [ball], self_collision=False)
    distance_m = np.array([collision.min_distance(q) for q in log.q])
    np.testing.assert_array_equal(contacts.per_sample["contacts_closest_m"], distance_m)
    assert contacts.closest_m == distance_m.min() and 0.0195 < contacts.closest_m < 0.03
    assert contacts.closest_t_s == log.t_s[np.argmin(distance_m)]
    assert contacts.closest_links[1] == "obstacle1"
    assert contacts.closest_links[0] in collision.link_names
    counted = replay_contacts(lbr4p, collision.obstacles, log.q)
    assert (contacts.obstacle.count, contacts.self_contact.count) == (0, 0)
    assert (counted.obstacle, counted.self_contact, counted.deepest_m) == (0, 0, 0.0)


def test_contacts_survive_a_save_and_a_load(lbr4p, tmp_path):
    collision = CollisionModel(lbr4p, [_PLANE], self_collision=True)
    rng = np.random.default_rng(7)
    qs = LBR4P_Q0 + 0.05 * rng.standard_normal((12, lbr4p.nq))
    log = _log(qs)
    contacts = measure_contacts(lbr4p, collision, log.q, log.t_s)
    assert contacts.obstacle.count > 0 and contacts.obstacle.samples == 12
    assert contacts.obstacle.deepest_m > 0.0 and contacts.closest_m < 0.0
    assert contacts.self_collision
    counted = replay_contacts(lbr4p, collision.obstacles, qs)
    assert contacts.obstacle.count == counted.obstacle
    assert contacts.self_contact.count == counted.self_contact
    assert contacts.deepest_m == counted.deepest_m
    save_run(_result(log, contacts), tmp_path, "cut")
    loaded, record = load_run(tmp_path / "cut.json")
    back = loaded_contacts(record)
    assert back == contacts  # every summary field
    for key in CONTACT_COLUMNS:
        np.testing.assert_array_equal(back.per_sample[key], contacts.per_sample[key])
    stored = json.loads((tmp_path / "cut.json").read_text())["contacts"]
    assert stored["robot_obstacle"]["count"] == contacts.obstacle.count
    assert stored["closest"]["links"] == list(contacts.closest_links)


def test_a_run_without_contacts_says_not_checked_and_an_old_file_not_recorded(tmp_path):
    log = _log(np.tile(LBR4P_Q0, (3, 1)))
    save_run(_result(log), tmp_path, "plain")
    _, record = load_run(tmp_path / "plain.json")
    assert record["contacts"] == {"checked": False} and loaded_contacts(record) is None
    assert "not checked" in contacts_text(record)
    old = json.loads((tmp_path / "plain.json").read_text())
    del old["contacts"]  # as written before contacts were saved
    (tmp_path / "plain.json").write_text(json.dumps(old))
    old_log, old_record = load_run(tmp_path / "plain.json")
    np.testing.assert_array_equal(old_log.q, log.q)
    assert loaded_contacts(old_record) is None
    assert contacts_text(old_record).startswith("contacts: not recorded")
