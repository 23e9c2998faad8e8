"""Result tables of ``dqcontrol.experiments.tables``: cells, Markdown and CSV from hand-made rows,
checked line by line and read back with the csv module."""

from __future__ import annotations

import csv
import io
import math

import pytest

from dqcontrol.experiments.tables import csv_text, format_cell, markdown_table

COLUMNS = (("traj", "trajectory", "s"), ("T", "T_tot [s]", "g"), ("e", "e_mean", ".2e"))
ROWS = [
    {"traj": "circle", "T": 2.0, "e": 1.23456e-4},
    {"traj": "sinusoid", "T": 4, "e": math.nan},
    {"traj": "turn", "T": None, "e": 0.1 + 0.2},
]


@pytest.mark.parametrize(
    ("value", "spec", "cell"),
    [
        (None, ".3f", "—"),
        (math.nan, ".3f", "nan"),
        (-math.inf, "g", "nan"),
        (1.23456, ".3f", "1.235"),
        (7, "d", "7"),
        (["a", 1], "s", "['a', 1]"),
        (True, "s", "True"),
    ],
)
def test_cells(value, spec, cell):
    assert format_cell(value, spec) == cell


def test_markdown_table():
    assert markdown_table(ROWS, COLUMNS).splitlines() == [
        "| trajectory | T_tot [s] | e_mean |",
        "|---|---|---|",
        "| circle | 2 | 1.23e-04 |",
        "| sinusoid | 4 | nan |",
        "| turn | — | 3.00e-01 |",
    ]


def test_csv_keeps_full_precision_and_leaves_none_empty():
    text = csv_text(ROWS, COLUMNS)
    rows = list(csv.reader(io.StringIO(text)))
    assert rows[0] == ["traj", "T", "e"]
    assert rows[1] == ["circle", "2.0", "0.000123456"]
    assert rows[2] == ["sinusoid", "4", "nan"]
    assert rows[3] == ["turn", "", "0.30000000000000004"]
    assert float(rows[3][2]) == 0.1 + 0.2  # repr: the float itself
    assert csv_text([], COLUMNS) == "traj,T,e\n"
