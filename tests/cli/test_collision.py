"""Obstacles from the command line and in the viewer (docs/theory.md §10.6):
``dqcontrol run --obstacle …`` (bad input exits with 2), the report of the smallest distance
and of the contacts, and the obstacles drawn in the HTML replay."""

from __future__ import annotations

import base64
import json
import re

import numpy as np
import pytest
import umsgpack

from dqcontrol import load_lbr4p
from dqcontrol.cli import main
from dqcontrol.model import LBR4P_Q0
from dqcontrol.model.collision import Box, Capsule, Cylinder, HalfSpace, Sphere
from dqcontrol.viz.meshcat_viewer import MeshcatViewer

#: A ball on the circle's path at σ = 1 s (the circle at 2 s from the LBR4p's start posture).
BALL = "sphere:0.4865,-0.3922,0.7006,0.03"


@pytest.mark.parametrize(
    ("option", "message"),
    [
        ("cone:1,2,3", "unknown obstacle shape 'cone'"),
        ("sphere:0,0,1,-0.1", "radius_m"),
        ("sphere:nan,0,1,0.1", "position_m must be finite"),
        ("sphere:0,0,inf,0.1", "position_m must be finite"),
        ("box:0,0,1,0.1,0.1", "6 numbers"),
        ("box:0,0,1,0.1,-0.1,0.1", "size_m"),
        ("plane:0,0,0,0.3", "normal"),
        ("capsule:0,0,1,0.1,x", "number"),
    ],
)
def test_bad_obstacles_exit_2(option, message, capsys, tmp_path):
    with pytest.raises(SystemExit) as exc:
        main(["run", "--simulator", "kinematic", "--obstacle", option, "--out", str(tmp_path)])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "--obstacle" in err and message in err


def test_a_controller_without_limits_is_refused(capsys, tmp_path):
    with pytest.raises(SystemExit) as exc:
        main(["run", "--controllers", "proportional", "--obstacle", BALL, "--out", str(tmp_path)])
    assert exc.value.code == 2
    assert "takes no limits" in capsys.readouterr().err


def test_the_help_gives_the_forms_and_units(capsys):
    with pytest.raises(SystemExit):
        main(["run", "--help"])
    out = " ".join(capsys.readouterr().out.split())
    for form in ("sphere:X,Y,Z,R", "box:X,Y,Z,SX,SY,SZ", "plane:NX,NY,NZ,D", "metres"):
        assert form in out


def test_run_with_an_obstacle_reports_distance_and_contacts(capsys, tmp_path):
    code = main(
        [
            "run", "--simulator", "kinematic", "--controllers", "pf", "--period", "0.01",
            "--duration", "2", "--obstacle", BALL, "--short", "--out", str(tmp_path),
        ]
    )  # fmt: skip
    assert code == 1  # the path is blocked: the task does not complete
    out, err = capsys.readouterr()
    stop = re.search(r"pf did not complete the trajectory: the phase reached ([\d.]+) s of "
                     r"T_tot = 2 s, where it stopped \(s = 0\)", err)  # fmt: skip
    assert stop is not None, err
    assert 0.5 < float(stop.group(1)) < 1.0  # before the ball, which is on the path at 1 s
    line = re.search(
        r"pf: min distance ([\d.]+) mm; contacts robot-obstacle (\d+), self (\d+)", out
    )
    assert line is not None, out
    assert float(line.group(1)) >= 19.5 and line.group(2) == "0" and line.group(3) == "0"
    folder = tmp_path / "lbr4p_circle_T2s_kinematic"
    meta = json.loads((folder / "pf.json").read_text())
    assert meta["meta"]["obstacles"] == [BALL]
    html = (folder / "pf_replay.html").read_text()
    assert "/meshcat/dqcontrol/obstacles/obstacle1/0" in _object_paths(html)


def _object_paths(html: str) -> set[str]:
    blobs = re.findall(r"data:application/octet-binary;base64,([A-Za-z0-9+/=]+)", html)
    cmds = [umsgpack.unpackb(base64.b64decode(b)) for b in blobs]
    return {c["path"] for c in cmds if c["type"] == "set_object"}


def _transforms(html: str) -> dict[str, np.ndarray]:
    blobs = re.findall(r"data:application/octet-binary;base64,([A-Za-z0-9+/=]+)", html)
    cmds = [umsgpack.unpackb(base64.b64decode(b)) for b in blobs]
    return {
        c["path"]: np.array(c["matrix"], dtype=float).reshape(4, 4).T
        for c in cmds
        if c["type"] == "set_transform"
    }


def test_the_viewer_draws_every_shape_where_it_is():
    shapes = (
        Sphere(name="ball", position_m=(0.5, 0.0, 0.6), radius_m=0.05),
        Box(name="crate", position_m=(0.3, -0.5, 0.4), size_m=(0.2, 0.1, 0.3)),
        Capsule(name="pole", position_m=(-0.4, 0.3, 0.8), radius_m=0.04, length_m=0.5),
        Cylinder(name="drum", position_m=(0.0, 0.6, 0.4), radius_m=0.1, length_m=0.3),
        HalfSpace(name="table", normal=(0.0, 0.0, 1.0), offset_m=0.45),
    )
    viewer = MeshcatViewer(load_lbr4p(), live=False, q=LBR4P_Q0)
    viewer.show_obstacles(shapes)
    html = viewer.static_html()
    paths = _object_paths(html)
    root = "/meshcat/dqcontrol/obstacles"
    for name, parts in (("ball", 1), ("crate", 1), ("pole", 3), ("drum", 1), ("table", 1)):
        assert {f"{root}/{name}/{k}" for k in range(parts)} <= paths
    moves = _transforms(html)
    assert np.allclose(moves[f"{root}/ball/0"][:3, 3], [0.5, 0.0, 0.6])
    # the capsule's end spheres lie on its axis, half a length from the centre
    assert np.allclose(moves[f"{root}/pole/1"][:3, 3], [-0.4, 0.3, 0.55])
    # meshcat's cylinder runs along y: drawn turned onto the world z axis
    assert np.allclose(moves[f"{root}/drum/0"][:3, :3] @ [0, 1, 0], [0, 0, 1], atol=1e-12)
    # the table's slab has its top on the plane
    assert moves[f"{root}/table/0"][2, 3] == pytest.approx(0.45 - 0.005)
