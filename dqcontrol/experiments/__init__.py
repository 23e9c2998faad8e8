"""Experiments: ready-made sweeps that reproduce the thesis's results.

- :mod:`dqcontrol.experiments.table1` — the thesis's Table 1 grid (circle and sinusoid at
  four periods each, local vs predictive p = 6 and p = 10), run in parallel on a process
  pool or a Dask cluster, written to ``results/table1.md`` and ``.csv``.
"""

from dqcontrol.experiments.table1 import (
    THESIS_TABLE1,
    Table1Case,
    Table1Result,
    Table1Settings,
    run_case,
    run_table1,
    table1_cases,
)

__all__ = [
    "THESIS_TABLE1",
    "Table1Case",
    "Table1Result",
    "Table1Settings",
    "run_case",
    "run_table1",
    "table1_cases",
]
