"""The compiled linearisation check of the path-following step
(dqcontrol/controllers/path_following/kernels.py) against the same mismatch formed with
numpy (seeded random draws)."""

from __future__ import annotations

import numpy as np
import pytest

from dqcontrol.controllers.path_following.kernels import tangent_mismatch
from dqcontrol.controllers.terms.path_error import PROJECTOR_BASIS, tangent_projectors


@pytest.mark.parametrize(("seed", "flip"), [(0, False), (1, True), (2, False)])
def test_tangent_mismatch_is_the_largest_difference_of_the_errors(seed, flip):
    rng = np.random.default_rng(seed)
    x = rng.normal(size=8)
    xd = (-1.0 if flip else 1.0) * (x + rng.normal(scale=0.1, size=8))
    rows, b, z = rng.normal(size=(9, 12)), rng.normal(size=9), rng.normal(size=12)
    aligned = -x if float(x @ xd) < 0.0 else x
    true = tangent_projectors(aligned[None, :])[0] @ (aligned - xd)
    expected = np.max(np.abs(true - (rows[:6] @ z - b[:6])))
    got = tangent_mismatch(x, xd, PROJECTOR_BASIS, rows, b, z)
    assert got == pytest.approx(expected, rel=1e-13, abs=1e-15)
    b[2] = np.nan
    assert np.isnan(tangent_mismatch(x, xd, PROJECTOR_BASIS, rows, b, z))
