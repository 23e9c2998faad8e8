"""The DAQP backend keeps no stale equality: a row that happens to have lower == upper at
the first solve after a setup (a joint braking at a conflict) must move freely once its
bounds widen again."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from dqcontrol.controllers.qp_daqp import DaqpQP


def _qp(**kwargs) -> DaqpQP:
    pattern = sp.csc_matrix(np.triu(np.ones((2, 2))))
    return DaqpQP(pattern, sp.identity(2, format="csc"), **kwargs)


def _values(h: np.ndarray) -> np.ndarray:
    """The upper triangle of ``h`` in CSC order (the controllers' p_values)."""
    return np.array([h[0, 0], h[0, 1], h[1, 1]])


H = np.eye(2)
C = np.array([-0.5, 0.0])  # unconstrained optimum x = (0.5, 0)


def test_a_collapsed_box_at_setup_is_not_kept_as_an_equality():
    qp = _qp()
    first = qp.solve(_values(H), C, np.array([0.2, -1.0]), np.array([0.2, 1.0]))
    assert first.ok
    np.testing.assert_allclose(first.x, [0.2, 0.0], atol=1e-12)
    wide = qp.solve(_values(H), C, np.array([-1.0, -1.0]), np.array([1.0, 1.0]))
    assert wide.ok
    np.testing.assert_allclose(wide.x, [0.5, 0.0], atol=1e-12)  # was 0.2 or 1.0: pinned


def test_equalities_by_design_stay_fixed():
    qp = _qp(equality_rows=np.array([1]))
    lo, up = np.array([-1.0, 0.3]), np.array([1.0, 0.3])
    for _ in range(3):
        sol = qp.solve(_values(H), C, lo, up)
        assert sol.ok
        np.testing.assert_allclose(sol.x, [0.5, 0.3], atol=1e-12)
