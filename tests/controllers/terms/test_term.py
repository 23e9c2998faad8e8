"""The term contract (dqcontrol/controllers/terms/term.py): ``residual`` is the one method to
write; the hooks and the Gram fast path default to doing nothing (docs/theory.md §7.3)."""

from __future__ import annotations

import numpy as np
import pytest

from dqcontrol.controllers.core.problem import Residual
from dqcontrol.controllers.terms.term import Term


class Zero(Term):
    """The smallest term: one row ``z_0``."""

    def residual(self, ctx):
        a = np.zeros((1, 3))
        a[0, 0] = 1.0
        return Residual(self.name, self.weight, np.zeros(1), A=a)


def test_a_term_without_residual_cannot_be_made():
    class NoRows(Term):
        pass

    with pytest.raises(TypeError, match="residual"):
        NoRows()


def test_the_hooks_default_to_nothing_and_no_fast_path():
    term = Zero()
    assert term.name == "term" and term.weight == 1.0
    hessian = np.arange(18.0).reshape(2, 3, 3)
    before = hessian.copy()
    assert term.add_gram(None, hessian) is False
    np.testing.assert_array_equal(hessian, before)  # left as it was
    assert term.prepare(None) is None and term.reset() is None
    assert term.observe(np.ones(3), 0.5) is None and term.observe(None, 0.0) is None
