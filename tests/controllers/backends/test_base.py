"""The backend contract's helpers (:mod:`dqcontrol.controllers.backends.base`): bounds a solver
must never see, and the registry's names; the contract itself is tested over a backend
written outside the package in ``test_contract.py``."""

from __future__ import annotations

import time

import numpy as np
import pytest

from dqcontrol.controllers.backends.base import (
    DEFAULT_SOLVER,
    backend_names,
    check_backend_name,
    invalid_bounds,
    make_backend,
    refused_bounds,
)
from dqcontrol.controllers.backends.daqp.backend import DaqpBackend
from dqcontrol.controllers.backends.osqp import OsqpBackend
from dqcontrol.errors import ParameterError


def test_bounds_crossed_or_nan_are_refused_with_their_rows():
    start = time.perf_counter()
    assert invalid_bounds(np.array([-1.0, 0.0, 2.0]), np.array([1.0, 0.0, 2.0]), start) is None
    lower = np.array([0.0, 1.0, np.nan, -np.inf, 3.0])
    upper = np.array([1.0, 0.5, 1.0, np.inf, np.nan])
    sol = invalid_bounds(lower, upper, start)
    assert sol is not None and not sol.ok and sol.x is None
    assert sol.status == "invalid_bounds: lower > upper or NaN in rows [1, 2, 4]"
    assert sol.solve_time_s >= 0.0
    many = refused_bounds(np.ones(9), np.zeros(9), start)
    assert many.status.endswith("rows [0, 1, 2, 3, 4]")  # the first five


def test_backend_names_and_their_checks():
    names = backend_names()
    assert names[0] == DEFAULT_SOLVER == "daqp" and "osqp" in names
    assert check_backend_name(None) == "daqp"
    assert check_backend_name("OSQP") == "osqp"
    with pytest.raises(ParameterError, match=r"solver must be one of 'daqp', .*got 'qpoases'"):
        check_backend_name("qpoases")
    with pytest.raises(ParameterError, match="solver must be one of"):
        check_backend_name(3)


def test_make_backend_builds_the_registered_backend():
    assert type(make_backend(None)) is DaqpBackend
    assert type(make_backend("osqp", {"max_iter": 50})) is OsqpBackend
