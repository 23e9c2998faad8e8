"""Exceptions of dqcontrol: every error the library raises derives from :class:`DQControlError`.

Each error carries its evidence in the message: what was wrong and what would be right.
"""

from __future__ import annotations


class DQControlError(Exception):
    """Base class of every error raised by dqcontrol."""


class URDFError(DQControlError):
    """A robot description could not be read: missing file, malformed XML, bad values."""


class FrameError(DQControlError, KeyError):
    """An unknown frame name was requested; the message lists the frames that exist."""

    def __str__(self) -> str:  # KeyError would quote the message; keep it readable
        return str(self.args[0]) if self.args else ""


class ConfigurationError(DQControlError, ValueError):
    """A joint vector (q, qd, ...) has the wrong size or holds NaN/inf."""


class ParameterError(DQControlError, ValueError):
    """A parameter is outside its accepted range; the message names it and the range."""


class SolverError(DQControlError):
    """A QP solver failed. Raised only outside control loops; loops fall back instead."""


class MissingExtraError(DQControlError, ImportError):
    """An optional dependency is not installed; the message names the extra that brings it
    (``pip install 'dqcontrol[sim]'``)."""


def user_interrupt(exc: BaseException) -> bool:
    """Whether ``exc`` is the user's interrupt: a :class:`KeyboardInterrupt` (Ctrl-C, or a
    termination signal a handler turns into one), or an error that wraps one. A signal's
    handler runs in whatever Python code the main thread is in; where that is a callback of
    compiled code (Numba fetching a constant while it returns an array), the interrupt comes
    back as a ``SystemError`` whose cause is the :class:`KeyboardInterrupt`, and a loop that
    waited for the interrupt alone would end without braking or saving its run."""
    seen: set[int] = set()
    current: BaseException | None = exc
    while current is not None and id(current) not in seen:
        if isinstance(current, KeyboardInterrupt):
            return True
        seen.add(id(current))
        current = current.__cause__ or current.__context__
    return False
