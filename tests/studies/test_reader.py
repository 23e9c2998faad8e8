"""``dqcontrol.studies.reader``: values of each kind taken or refused, defaults, sub-tables and
unknown keys, with messages naming the file, table, key, the value found and what is expected."""

from __future__ import annotations

import math

import pytest

from dqcontrol.errors import ParameterError
from dqcontrol.studies.reader import REQUIRED, TOP_LEVEL, StudyFileError, TableReader


def _reader(where: str = "[grid]", **data) -> TableReader:
    return TableReader(data, where, "study.toml")


@pytest.mark.parametrize(
    ("kind", "good", "bad"),
    [
        ("str", "circle", "  "),
        ("bool", False, 0),
        ("int", 3, True),
        ("number", -2.5, math.inf),
        ("positive", 0.05, 0),
        ("numbers", [1, 2.5], [1, "2"]),
        ("positives", [1.0, 2.0], []),
        ("strs", ["local"], ["local", 1]),
        ("matrix", [[0, 1], [2.5]], [0, 1]),
        ("table", {"a": 1}, [1]),
        ("tables", [{"a": 1}], [{}, 1]),
    ],
)
def test_each_kind_is_taken_or_refused(kind, good, bad):
    assert _reader(value=good).take("value", kind) == good
    with pytest.raises(StudyFileError, match="study.toml: \\[grid\\] value: expected "):
        _reader(value=bad).take("value", kind)


def test_the_message_shows_the_value_its_type_and_the_unit():
    with pytest.raises(StudyFileError) as info:
        _reader("[simulator]", period_s="fast").take("period_s", "positive", unit="s")
    assert str(info.value) == (
        "study.toml: [simulator] period_s: expected a finite number > 0 [s], got 'fast' (str)"
    )
    with pytest.raises(StudyFileError) as info:
        _reader(value="x" * 100).take("value", "int")
    assert str(info.value).endswith("got '" + "x" * 56 + "... (str)")  # long values cut
    assert issubclass(StudyFileError, ParameterError)


def test_a_missing_key_takes_its_default_or_is_required():
    reader = _reader()
    assert reader.take("controllers", "strs", ("local",)) == ("local",)
    assert not reader.has("controllers")
    with pytest.raises(
        StudyFileError, match="\\[grid\\] duration_s: missing; expected a non-empty"
    ):
        reader.take("duration_s", "positives", REQUIRED)
    assert repr(REQUIRED) == "REQUIRED"


def test_top_level_keys_are_named_as_tables():
    reader = _reader(TOP_LEVEL, grid=3)
    with pytest.raises(
        StudyFileError, match="study.toml: \\[grid\\]: expected a table, got 3 \\(int\\)"
    ):
        reader.child("grid")
    assert str(reader.error(None, "empty file")) == "study.toml: at the top level: empty file"


def test_sub_tables_are_named_after_their_parents():
    top = _reader(TOP_LEVEL, options={"p10": {"horizon_s": "one"}})
    options = top.child("options")
    assert options.where == "[options]"
    p10 = options.child("p10")
    assert p10.where == "[options.p10]"
    with pytest.raises(
        StudyFileError, match="\\[options.p10\\] horizon_s: expected a finite number"
    ):
        p10.take("horizon_s", "positive")
    assert options.child("local").data == {}  # absent: empty
    with pytest.raises(StudyFileError, match="\\[options\\] pf: missing; expected a table"):
        options.child("pf", default_empty=False)


def test_unknown_keys_are_named_with_the_known_ones():
    reader = _reader(controllers=["local"], duration_s=[1.0], colour="red", size=2)
    reader.take("controllers", "strs")
    assert reader.rest() == {"duration_s": [1.0], "colour": "red", "size": 2}
    reader.take("duration_s", "positives")
    with pytest.raises(StudyFileError) as info:
        reader.finish()
    assert str(info.value) == (
        "study.toml: unknown key 'colour', 'size' in [grid]; known keys there: controllers, "
        "duration_s"
    )
    _reader(TOP_LEVEL, grid={}).finish(["grid", "study"])  # every key known
    with pytest.raises(
        StudyFileError, match="unknown key 'x' at the top level; known keys there: none"
    ):
        _reader(TOP_LEVEL, x=1).finish([])
