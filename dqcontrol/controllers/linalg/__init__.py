"""Small dense linear algebra in compiled calls, for the kilohertz loop: Cholesky factors,
Householder QR and null-space bases, Gram matrices, the non-zero entries of sparse rows,
and numpy's summation order (docs/theory.md §7.4–7.5); the null-space bases are in
:mod:`~dqcontrol.controllers.linalg.null_space`."""

from dqcontrol.controllers.linalg.cholesky import cholesky_into
from dqcontrol.controllers.linalg.entries import nonzero_entries, stacked_entries
from dqcontrol.controllers.linalg.gram import frozen
from dqcontrol.controllers.linalg.lanes import lane_dot

__all__ = [
    "cholesky_into",
    "frozen",
    "lane_dot",
    "nonzero_entries",
    "stacked_entries",
]
