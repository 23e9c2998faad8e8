"""A node's life in a process: rclpy started with the node's ``--ros-args``, the node's
parameters read and checked, the executor spun, and everything shut down at the end."""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterator, Sequence
from typing import Any, TypeVar

from dqcontrol.ros2.params import ControlParams, SimParams
from dqcontrol.ros2.ros import require_ros

__all__ = ["ros_node", "spin_in_background"]

_P = TypeVar("_P", ControlParams, SimParams)

#: Parameters every rclpy node declares itself (not the node's own).
_RCLPY_OWN = {"use_sim_time", "start_type_description_service"}


def _raise_interrupt(signum: int, frame: Any) -> None:
    del signum, frame
    raise KeyboardInterrupt


@contextlib.contextmanager
def ros_node(name: str, ros_args: Sequence[str], params_type: type[_P]) -> Iterator[tuple[Any, _P]]:
    """A node named ``name`` taking every parameter given, and its checked parameters, in
    an rclpy context started with ``ros_args`` (what follows ``--ros-args``).

    Ctrl-C and SIGTERM raise :class:`KeyboardInterrupt` in the main thread (rclpy's own
    handlers would shut the context down before the node could brake).

    Raises:
        MissingExtraError: no rclpy (the ``[ros2]`` extra).
        ParameterError: a bad parameter (one line naming it).
    """
    ros = require_ros()
    rclpy = ros.rclpy
    from rclpy.signals import SignalHandlerOptions

    context = rclpy.context.Context()
    rclpy.init(
        args=["dqcontrol", "--ros-args", *ros_args],
        context=context,
        signal_handler_options=SignalHandlerOptions.NO,
    )
    previous = signal.signal(signal.SIGTERM, _raise_interrupt)
    node = None
    try:
        node = rclpy.create_node(
            name,
            context=context,
            allow_undeclared_parameters=True,
            automatically_declare_parameters_from_overrides=True,
        )
        given = node.get_parameters_by_prefix("")
        values = {k: p.value for k, p in given.items() if k not in _RCLPY_OWN}
        yield node, params_type.from_values(values)
    finally:
        signal.signal(signal.SIGTERM, previous)
        if node is not None:
            node.destroy_node()
        context.try_shutdown()


@contextlib.contextmanager
def spin_in_background(node: Any) -> Iterator[None]:
    """The node's callbacks served by an executor in a daemon thread while the block runs."""
    ros = require_ros()
    executor = ros.rclpy.executors.SingleThreadedExecutor(context=node.context)
    executor.add_node(node)
    thread = threading.Thread(target=executor.spin, name="rclpy executor", daemon=True)
    thread.start()
    try:
        yield
    finally:
        executor.shutdown(timeout_sec=1.0)
        thread.join(timeout=1.0)
