"""``dqcontrol.studies.kinds``: every experiment found by its name, an unknown name an error listing
the known ones, and an experiment's defaults."""

from __future__ import annotations

from dataclasses import FrozenInstanceError
from types import SimpleNamespace

import pytest

from dqcontrol.studies.kinds import EXPERIMENTS, ExperimentKind, RunInfo, experiment_kind
from dqcontrol.studies.reader import TOP_LEVEL, StudyFileError, TableReader


@pytest.mark.parametrize("name", EXPERIMENTS)
def test_every_experiment_is_found_by_its_name(name):
    kind = experiment_kind(name)
    assert isinstance(kind, ExperimentKind) and kind.name == name
    assert callable(kind.cases) and callable(kind.render) and callable(kind.job)


def test_what_each_experiment_keeps_and_reads():
    assert experiment_kind("table1").save_runs_default
    assert not experiment_kind("tracking").save_runs_default
    assert "options" in experiment_kind("tracking").own_tables
    assert "faults" in experiment_kind("faults").own_tables


def test_an_unknown_experiment_lists_the_known_ones():
    with pytest.raises(StudyFileError) as info:
        experiment_kind("x")
    assert str(info.value) == "unknown experiment 'x'; known: tracking, table1, faults, arms"
    reader = TableReader({"study": {}}, "[study]", "s.toml")
    with pytest.raises(StudyFileError) as info:
        experiment_kind("x", reader)
    assert str(info.value).startswith("s.toml: [study] experiment: unknown experiment 'x'")
    assert TOP_LEVEL == "at the top level"


def test_an_experiment_s_defaults():
    def unused(*args):
        raise AssertionError("not called")

    kind = ExperimentKind("mine", *([unused] * 9))
    assert kind.cost(SimpleNamespace(duration_s=3.5)) == 3.5  # the longest cases first
    assert kind.own_tables == () and not kind.save_runs_default and kind.can_save_runs
    info = RunInfo(1.5, "in-process (1 worker)", "dqcontrol study s.toml", False, 2)
    with pytest.raises(FrozenInstanceError):
        info.total_cases = 3
