"""The exceptions of ``dqcontrol.errors``: one base class, the standard classes each one also is
(so ``except KeyError`` / ``ValueError`` / ``ImportError`` keep working), readable messages."""

from __future__ import annotations

import inspect

import pytest

from dqcontrol import errors
from dqcontrol.errors import (
    ConfigurationError,
    DQControlError,
    FrameError,
    MissingExtraError,
    ParameterError,
    SolverError,
    URDFError,
)


def test_every_error_derives_from_dqcontrol_error():
    for cls in (ConfigurationError, FrameError, ParameterError, URDFError):
        assert issubclass(cls, DQControlError)


def test_every_error_here_is_a_dqcontrol_error():
    for cls in (URDFError, ParameterError, ConfigurationError, FrameError):
        assert issubclass(cls, DQControlError)


def test_every_exception_class_of_the_module_derives_from_the_base():
    classes = [
        obj
        for _, obj in inspect.getmembers(errors, inspect.isclass)
        if issubclass(obj, BaseException) and obj.__module__ == errors.__name__
    ]
    assert len(classes) == 7
    assert all(issubclass(cls, DQControlError) for cls in classes)
    assert DQControlError.__bases__ == (Exception,)


@pytest.mark.parametrize(
    ("cls", "standard"),
    [
        (FrameError, KeyError),
        (ConfigurationError, ValueError),
        (ParameterError, ValueError),
        (MissingExtraError, ImportError),
    ],
)
def test_each_error_is_also_the_standard_error_callers_catch(cls, standard):
    with pytest.raises(standard, match="the evidence"):
        raise cls("the evidence")


def test_a_frame_error_reads_as_its_message_not_a_quoted_key():
    message = "unknown frame 'tool0'; frames of this robot: ['flange']"
    assert str(FrameError(message)) == message
    assert str(KeyError(message)) == repr(message)  # what KeyError alone would print
    assert str(FrameError()) == ""


def test_solver_and_urdf_errors_are_not_value_errors():
    """Callers that catch ValueError for bad arguments must not swallow these."""
    for cls in (SolverError, URDFError):
        assert not issubclass(cls, ValueError | KeyError | ImportError)


def test_user_interrupt_finds_the_interrupt_behind_a_wrapped_error():
    from dqcontrol.errors import user_interrupt

    assert user_interrupt(KeyboardInterrupt())
    try:
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt as inner:
            raise SystemError("returned a result with an exception set") from inner
    except SystemError as exc:
        wrapped = exc
    assert user_interrupt(wrapped)
    try:
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt:
            raise SystemError("during handling") from None  # context kept, cause suppressed
    except SystemError as exc:
        assert user_interrupt(exc)
    assert not user_interrupt(SystemError("a real one"))
    assert not user_interrupt(ValueError("x"))
    looped = SystemError("a cycle")
    looped.__context__ = looped
    assert not user_interrupt(looped)
