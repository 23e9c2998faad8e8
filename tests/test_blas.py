"""One BLAS thread during a control step, the previous counts restored after it."""

import numpy as np
import scipy.linalg  # noqa: F401 - SciPy's BLAS is switched too: loaded before the counts are read
from threadpoolctl import threadpool_info

from dqcontrol._blas import single_blas_thread


def _blas_threads() -> list[int]:
    return [info["num_threads"] for info in threadpool_info() if info["user_api"] == "blas"]


def test_one_thread_inside_and_the_counts_restored_after():
    before = _blas_threads()
    assert before, "numpy's BLAS is loaded"
    with single_blas_thread():
        assert _blas_threads() == [1] * len(before)
        with single_blas_thread():  # nested: still one, and the outer exit restores
            assert _blas_threads() == [1] * len(before)
        assert _blas_threads() == [1] * len(before)
    assert _blas_threads() == before


def test_the_counts_are_restored_when_the_block_raises():
    before = _blas_threads()
    try:
        with single_blas_thread():
            raise RuntimeError("a failing step")
    except RuntimeError:
        pass
    assert _blas_threads() == before


def test_a_path_following_step_runs_with_one_thread(lbr4p):
    from dqcontrol.controllers import PathFollowingController
    from dqcontrol.controllers.core import levels
    from dqcontrol.model import LBR4P_Q0
    from dqcontrol.trajectories import Circle

    seen = []
    solve = levels._solve_levels

    def spy(problem, backend):
        seen.append(_blas_threads())
        return solve(problem, backend)

    levels._solve_levels = spy
    try:
        ctrl = PathFollowingController(lbr4p, Circle(2.0), 0.01, num_intervals=4)
        ctrl.reset(LBR4P_Q0)
        before = _blas_threads()
        ctrl.step(LBR4P_Q0.copy())
    finally:
        levels._solve_levels = solve
    assert seen and all(counts == [1] * len(before) for counts in seen)
    assert _blas_threads() == before
    assert np.all(np.isfinite(ctrl.qd_prev))


def test_another_thread_inside_keeps_one_thread_until_it_leaves():
    """A thread's nested uses count in its own count: the main thread leaving its block
    does not restore the counts while another thread is still inside its own."""
    import threading

    before = _blas_threads()
    inside, leave = threading.Event(), threading.Event()

    def other() -> None:
        with single_blas_thread():
            inside.set()
            leave.wait(10.0)

    worker = threading.Thread(target=other)
    worker.start()
    try:
        assert inside.wait(10.0)
        with single_blas_thread():
            with single_blas_thread():
                assert _blas_threads() == [1] * len(before)
        assert _blas_threads() == [1] * len(before)  # the other thread is still inside
    finally:
        leave.set()
        worker.join(10.0)
    assert _blas_threads() == before


def test_the_control_loop_holds_one_thread_between_its_steps(lbr4p):
    """Between two steps of :func:`run_loop` the libraries stay at one thread (a step does
    not switch them itself), and the loop restores the counts it found."""
    from threadpoolctl import threadpool_limits

    from dqcontrol.controllers import LocalController
    from dqcontrol.model import LBR4P_Q0
    from dqcontrol.sim import KinematicDriver, run_loop
    from dqcontrol.trajectories import Circle

    seen = []
    with threadpool_limits(limits=2, user_api="blas"):
        before = _blas_threads()
        assert before == [2] * len(before)
        ctrl = LocalController(lbr4p, Circle(0.1), 0.01)
        run_loop(ctrl, KinematicDriver(lbr4p, 0.01), q0=LBR4P_Q0,
                 on_sample=lambda k, driver, result: seen.append(_blas_threads()))  # fmt: skip
        after = _blas_threads()
    assert len(seen) >= 10 and all(counts == [1] * len(before) for counts in seen)
    assert after == before
