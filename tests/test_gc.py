"""The garbage collector kept to young objects while a loop runs."""

import gc

from dqcontrol._gc import young_gc_only


class _Node:
    def __init__(self) -> None:
        self.me = self  # a cycle: only a collection frees it


def test_objects_from_before_are_frozen_and_new_cycles_still_collected():
    before = _Node()
    with young_gc_only():
        assert gc.get_freeze_count() > 0
        frozen = gc.get_freeze_count()
        _Node()  # garbage made in the block
        assert gc.collect() >= 1  # the block's own cycles are collected
        assert gc.get_freeze_count() == frozen and before.me is before
    assert gc.get_freeze_count() == 0


def test_a_caller_s_frozen_objects_stay_frozen():
    gc.freeze()
    try:
        count = gc.get_freeze_count()
        with young_gc_only():
            pass
        assert gc.get_freeze_count() >= count > 0
    finally:
        gc.unfreeze()


def test_disabled_leaves_the_collector_alone():
    with young_gc_only(enabled=False):
        assert gc.get_freeze_count() == 0
