"""``dqcontrol._compiled.compiled``: a kernel decorated with it computes what the plain Python
function computes, cached on disk where it can be, compiled in memory where it cannot."""

from __future__ import annotations

import numpy as np
from numba.core.registry import CPUDispatcher

from dqcontrol import _compiled
from dqcontrol._compiled import compiled


def _weighted_sum(values: np.ndarray, weight: float) -> float:
    total = 0.0
    for k in range(values.shape[0]):
        total += weight * values[k]
    return total


def test_a_compiled_kernel_equals_the_python_function():
    kernel = compiled(_weighted_sum)
    assert isinstance(kernel, CPUDispatcher)
    values = np.random.default_rng(51).normal(size=50)
    assert kernel(values, 0.5) == _weighted_sum(values, 0.5)


def test_without_a_cache_location_the_kernel_is_compiled_in_memory(monkeypatch):
    """Where Numba finds no writable cache location it refuses ``cache=True`` at decoration;
    ``compiled`` then compiles in memory instead of failing the import."""
    calls = []
    njit = _compiled.njit

    def refusing_cache(*args, **kwargs):
        calls.append(kwargs)
        if kwargs.get("cache"):
            raise RuntimeError("cannot cache function '_weighted_sum': no locator available")
        return njit(*args, **kwargs)

    monkeypatch.setattr(_compiled, "njit", refusing_cache)
    kernel = compiled(_weighted_sum)
    assert calls == [{"cache": True}, {}]
    assert not kernel.targetoptions.get("cache", False)
    values = np.arange(5.0)
    assert kernel(values, 2.0) == 20.0
