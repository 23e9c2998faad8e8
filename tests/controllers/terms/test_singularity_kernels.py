"""The singularity damping's compiled Cholesky check
(dqcontrol/controllers/terms/singularity_kernels.py) against the singular values of ``E J``,
on both sides of the threshold (docs/theory.md §8.3)."""

from __future__ import annotations

import numpy as np
import pytest
from controllers.terms.test_singularity_damping import pose_and_jacobian, smallest_singular_value

from dqcontrol.controllers.terms.path_error import PROJECTOR_BASIS
from dqcontrol.controllers.terms.singularity_kernels import clearly_regular


@pytest.mark.parametrize("n", [7, 6, 4])
@pytest.mark.parametrize("ratio", [0.3, 0.99, 0.999999, 1.000001, 1.01, 3.0])
def test_the_cholesky_check_agrees_with_the_singular_values(n, ratio):
    rng = np.random.default_rng(int(ratio * 1e6) + n)
    eps = 0.04
    k = min(6, n)
    values = np.sort(rng.uniform(0.2, 1.5, k))[::-1]
    values[-1] = ratio * eps
    x, jac = pose_and_jacobian(rng, values, n)
    assert smallest_singular_value(x, jac) == pytest.approx(ratio * eps, rel=1e-9)
    assert clearly_regular(x, jac, PROJECTOR_BASIS, eps * eps * (1.0 + 1e-9)) == (ratio > 1.0)


def test_nan_is_never_clear():
    x = np.full(8, np.nan)
    assert not clearly_regular(x, np.ones((8, 7)), PROJECTOR_BASIS, 1e-3)
