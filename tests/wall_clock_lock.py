"""Wall-clock tests run alone under pytest-xdist.

The suite runs on two workers (``-n 2`` in pyproject's addopts). A test that keeps a period
on the wall clock, or bounds a wall time, must not share the machine's cores with another
test: it would measure the other test. Every test therefore holds a lock on a file shared by
the workers while it runs (set-up, call and tear-down, so module fixtures that start
processes count too): a shared lock for an ordinary test, an exclusive one for a wall-clock
test. A second file is a turnstile: a waiting wall-clock test holds it, so new ordinary
tests queue behind it instead of keeping it waiting for ever.

A wall-clock test is one marked ``wall_clock``, or one whose source asks for a real-time
loop or reads the wall clock (:data:`WALL_CLOCK_WORDS`), so new ones are found without a
marker. Without xdist (one process) nothing is locked.
"""

from __future__ import annotations

import fcntl
import inspect
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

#: Words in a test function's source that make it a wall-clock test.
WALL_CLOCK_WORDS = ("realtime=True", "perf_counter", "CANARY")


def is_wall_clock(item: pytest.Item) -> bool:
    """Whether ``item`` keeps or measures wall time (marked, or by its source)."""
    if item.get_closest_marker("wall_clock") is not None:
        return True
    function = getattr(item, "function", None)
    if function is None:
        return False
    try:
        source = inspect.getsource(function)
    except (OSError, TypeError):
        return False
    return any(word in source for word in WALL_CLOCK_WORDS)


def lock_folder(config: pytest.Config) -> Path | None:
    """The folder the xdist workers share (their base temporary folders' parent), or
    ``None`` outside an xdist worker."""
    if not hasattr(config, "workerinput") or not config.option.basetemp:
        return None
    return Path(config.option.basetemp).resolve().parent


@contextmanager
def held(folder: Path, exclusive: bool) -> Iterator[None]:
    """Hold the suite's lock in ``folder``: exclusive for a wall-clock test, else shared."""
    with (
        open(folder / "turnstile.lock", "a") as turnstile,
        open(folder / "tests.lock", "a") as lock,
    ):
        if exclusive:
            fcntl.flock(turnstile, fcntl.LOCK_EX)
            fcntl.flock(lock, fcntl.LOCK_EX)
        else:
            fcntl.flock(turnstile, fcntl.LOCK_SH)
            fcntl.flock(lock, fcntl.LOCK_SH)
            fcntl.flock(turnstile, fcntl.LOCK_UN)
        try:
            yield
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)
            if exclusive:
                fcntl.flock(turnstile, fcntl.LOCK_UN)
