"""``dqcontrol view`` (dqcontrol/cli/view_cmd.py): a saved run's replay and figures rewritten,
replayed in the live viewer, its options checked before anything is loaded, a streamed run
read (a cut file flagged), and a run's contacts shown and drawn (or said not recorded)."""

from __future__ import annotations

import argparse
import json

import numpy as np
import pytest
from runs.test_contacts import (
    _log,
    _result,
    blocked_run,  # noqa: F401 - its module fixture, built here too
)

from dqcontrol.cli import main
from dqcontrol.controllers import LocalController
from dqcontrol.model.library import LBR4P_Q0
from dqcontrol.runs.contacts import loaded_contacts
from dqcontrol.runs.storage import load_run, save_run
from dqcontrol.sim import run_kinematic
from dqcontrol.trajectories import Circle
from dqcontrol.viz.figures import FIGURES


def test_view_rewrites_replay_and_figures(default_run, tmp_path, capsys):
    _, folder = default_run
    code = main(["view", str(folder / "p10.npz"), "--html", "--figures", "--out", str(tmp_path)])
    assert code == 0
    assert (tmp_path / "p10_replay.html").stat().st_size > 500_000
    assert len(list(tmp_path.glob("p10_*.png"))) == len(FIGURES)
    assert "wrote" in capsys.readouterr().out


def test_view_replays_in_the_live_viewer(default_run, capsys):
    _, folder = default_run
    code = main(["view", str(folder / "local.json"), "--hold", "0", "--speed", "2"])
    out = capsys.readouterr().out
    assert code == 0
    assert "Meshcat viewer: http://127.0.0.1:" in out and "replaying local" in out


def test_view_with_nothing_to_do_exits_2(default_run, capsys):
    _, folder = default_run
    with pytest.raises(SystemExit) as exc:
        main(["view", str(folder / "p10.npz"), "--no-viewer"])
    assert exc.value.code == 2
    assert "nothing to do" in capsys.readouterr().err


def test_a_negative_hold_exits_2_before_the_run_is_read(tmp_path, capsys):
    run = tmp_path / "run.json"
    run.write_text("not a run")  # never read: the options are checked first
    with pytest.raises(SystemExit) as exc:
        main(["view", str(run), "--hold", "-1"])
    assert exc.value.code == 2
    assert "--hold must be >= 0 seconds, got -1.0" in capsys.readouterr().err


def test_a_missing_run_names_the_files_looked_for(tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["view", str(tmp_path / "p10")])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "no saved run at" in err and "p10.json" in err and "p10.mcap" in err


def test_the_viewer_is_on_unless_files_are_asked_for(tmp_path):
    from dqcontrol.cli.view_cmd import _check_options

    run = tmp_path / "run.json"
    run.write_text("{}")
    parser = argparse.ArgumentParser()
    base = {"run": str(run), "hold": None, "_parser": parser}
    for given, viewer_on in (
        ({"viewer": None, "html": False, "figures": False}, True),
        ({"viewer": None, "html": True, "figures": False}, False),
        ({"viewer": None, "html": False, "figures": True}, False),
        ({"viewer": True, "html": True, "figures": False}, True),
    ):
        path, name, on = _check_options(argparse.Namespace(**base, **given))
        assert (path, name, on) == (run, "run", viewer_on), given


@pytest.mark.parametrize(("text", "ok"), [("0.25", True), ("0", False), ("inf", False)])
def test_speed_is_a_finite_positive_factor(text, ok):
    from dqcontrol.cli.view_cmd import _positive_speed

    if ok:
        assert _positive_speed(text) == float(text)
    else:
        with pytest.raises(argparse.ArgumentTypeError, match=r"\[x real time\]"):
            _positive_speed(text)


def _streamed(lbr4p, path, duration_s=1.0, **kwargs):
    controller = LocalController(lbr4p, Circle(duration_s), 0.01)
    return controller, run_kinematic(controller, LBR4P_Q0, log_file=path, **kwargs)


def test_view_reads_a_streamed_run_and_flags_a_cut(lbr4p, tmp_path, capsys, monkeypatch):
    import dqcontrol.viz.figures as figures

    drawn = []
    monkeypatch.setattr(figures, "plot_run", lambda log, *a, **k: drawn.append(log) or [])
    _, streamed = _streamed(lbr4p, tmp_path / "run.mcap", 0.3)
    data = streamed.log_file.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) - 200])  # the end record and summary lost
    for path in (streamed.log_file, cut):
        code = main(["view", str(path), "--no-viewer", "--figures", "--out", str(tmp_path / "v")])
        assert code == 0
    full, _ = load_run(streamed.log_file)
    assert [len(log) for log in drawn] == [len(full), len(full)]  # one block of 0.31 s
    err = capsys.readouterr().err
    assert "cut.mcap is incomplete" in err and "run.mcap" not in err


def test_view_shows_the_contacts_and_draws_them(blocked_run, tmp_path, capsys, monkeypatch):  # noqa: F811
    import dqcontrol.viz.figures as figures

    monkeypatch.setattr(figures, "plot_run", lambda *a, **k: [])
    _, folder = blocked_run
    code = main(["view", str(folder / "pf.json"), "--figures", "--out", str(tmp_path)])
    assert code == 0
    out = capsys.readouterr().out
    _, record = load_run(folder / "pf.json")
    assert f"contacts: {loaded_contacts(record).summary()}" in out
    assert "robot-obstacle 0, self 0" in out and "closest pair lbr4p_link_" in out
    assert (tmp_path / "pf_contacts.png").stat().st_size > 3000


def test_view_of_an_old_file_says_not_recorded(tmp_path, capsys, monkeypatch):
    import dqcontrol.viz.figures as figures

    monkeypatch.setattr(figures, "plot_run", lambda *a, **k: [])
    log = _log(np.tile(LBR4P_Q0, (3, 1)))
    log.meta.update(robot="lbr4p", simulator="kinematic")
    save_run(_result(log), tmp_path, "old")
    old = json.loads((tmp_path / "old.json").read_text())
    del old["contacts"]
    (tmp_path / "old.json").write_text(json.dumps(old))
    assert main(["view", str(tmp_path / "old.json"), "--figures"]) == 0
    assert "contacts: not recorded" in capsys.readouterr().out
    assert not (tmp_path / "old_contacts.png").exists()
