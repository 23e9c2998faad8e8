"""A small study file shared by the study tests: two short kinematic cases (the circle at
T_tot = 1 s, Local and p = 10), and a writer of study files."""

from __future__ import annotations

import textwrap
from pathlib import Path

#: Two short cases in the kinematic loop: the circle at T_tot = 1 s, Local and p = 10.
SMALL = """\
[study]
name = "small"

[simulator]
kind = "kinematic"
period_s = 0.05

[grid]
controllers = ["local", "p10"]
duration_s = [1.0]

[[trajectories]]
kind = "circle"
radius_m = 0.05

[options]
acceleration_limit = 10.0

[options.p10]
horizon_s = 0.5
"""


def write_study(folder: Path, text: str, name: str = "study.toml") -> Path:
    path = folder / name
    path.write_text(textwrap.dedent(text), encoding="utf-8")
    return path
