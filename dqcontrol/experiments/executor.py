"""Where the cases of an experiment run: in this process, on a local process pool, or on a
Dask distributed cluster.

Table 1 (:mod:`dqcontrol.experiments.table1`), the fault campaign
(:mod:`dqcontrol.faults.campaign`) and studies (:mod:`dqcontrol.studies`) hand their cases
to :func:`run_jobs`. A job is a picklable callable of one picklable case (a module-level
function, or a :func:`functools.partial` of one) that builds the robot, the trajectory,
the controller and the simulation inside the worker (Pinocchio and MuJoCo objects cannot be
pickled) and returns plain data.

- :class:`Executor` — the choice: ``workers`` processes (1: in this process) or a Dask
  scheduler address (``"local"``: a :class:`dask.distributed.LocalCluster` started here,
  one single-threaded worker process per requested worker);
- the pool's workers are fresh interpreters (``spawn``) with one BLAS/OpenMP thread each
  (:func:`single_threaded_children`): N workers on N cores would otherwise oversubscribe
  the cores;
- :func:`run_jobs` calls ``on_done(result)`` in this process as each case finishes, in
  completion order; an exception (Ctrl-C included) cancels the cases not yet started and
  propagates.
"""

from __future__ import annotations

import logging
import os
import sys
import uuid
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from contextlib import contextmanager
from dataclasses import dataclass
from multiprocessing import get_context
from typing import Any

from dqcontrol.errors import ConfigurationError, ParameterError

__all__ = [
    "DASK_CONNECT_TIMEOUT_S",
    "LOCAL_SCHEDULER",
    "THREAD_VARIABLES",
    "Executor",
    "progress_bar",
    "resolve_executor",
    "run_jobs",
    "single_threaded_children",
]

#: How long to wait for a Dask scheduler to answer [s].
DASK_CONNECT_TIMEOUT_S = 30.0
#: Scheduler address that starts a Dask cluster of local worker processes.
LOCAL_SCHEDULER = "local"
#: Thread-count variables of the BLAS/OpenMP runtimes, set to 1 in the workers.
THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


@dataclass(frozen=True)
class Executor:
    """Where the cases run.

    Attributes:
        workers: processes of the local pool (1: in this process); with ``scheduler =
            "local"``, the worker processes of the local Dask cluster.
        scheduler: address of a Dask distributed scheduler (``"tcp://host:8786"``),
            :data:`LOCAL_SCHEDULER`, or ``None`` for the local pool.
    """

    workers: int = 1
    scheduler: str | None = None

    @property
    def label(self) -> str:
        """How reports name it (``process pool, 4 workers``, ``Dask distributed at ...``)."""
        if self.scheduler == LOCAL_SCHEDULER:
            return f"Dask distributed, local cluster of {self.workers} worker processes"
        if self.scheduler:
            return f"Dask distributed at {self.scheduler}"
        if self.workers == 1:
            return "in-process (1 worker)"
        return f"process pool, {self.workers} workers"


def resolve_executor(workers: int | None, scheduler: str | None, cases: int) -> Executor:
    """The executor for ``cases`` cases: ``workers`` defaults to every core and is capped at
    the number of cases; ``scheduler`` as for :class:`Executor`.

    Raises:
        ParameterError: ``workers`` below 1 or not an integer.
    """
    if workers is not None and (
        isinstance(workers, bool) or not isinstance(workers, int) or workers < 1
    ):
        raise ParameterError(f"workers must be an integer ≥ 1, got {workers!r}")
    n = (os.cpu_count() or 1) if workers is None else workers
    n = max(1, min(n, cases))
    if scheduler is not None and not scheduler.strip():
        raise ParameterError("scheduler must be an address such as tcp://host:8786 or 'local'")
    return Executor(workers=n, scheduler=scheduler)


def progress_bar(total: int, description: str, enabled: bool):
    """A tqdm progress bar on stderr (disabled: the same object, silent)."""
    from tqdm.auto import tqdm

    return tqdm(total=total, desc=description, unit="case", disable=not enabled, file=sys.stderr)


@contextmanager
def single_threaded_children() -> Iterator[None]:
    """Environment for starting workers: one BLAS/OpenMP thread each, unless the user set
    these variables (:data:`THREAD_VARIABLES`)."""
    saved = {k: os.environ.get(k) for k in THREAD_VARIABLES}
    for k, v in saved.items():
        if v is None:
            os.environ[k] = "1"
    try:
        yield
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)


def run_jobs(
    job: Callable[[Any], Any],
    cases: Sequence[Any],
    executor: Executor,
    on_done: Callable[[Any], None],
    *,
    connect_timeout_s: float = DASK_CONNECT_TIMEOUT_S,
) -> None:
    """Run ``job(case)`` for every case on ``executor``; ``on_done(result)`` in this process
    as each finishes.

    Raises:
        ConfigurationError: a pool worker died, Dask is not installed, or its scheduler
            does not answer within ``connect_timeout_s``.
    """
    if executor.scheduler:
        _run_dask(job, cases, executor, on_done, connect_timeout_s)
    elif executor.workers == 1:
        for case in cases:
            on_done(job(case))
    else:
        _run_pool(job, cases, executor.workers, on_done)


def _run_pool(job, cases, workers: int, on_done) -> None:
    # spawn: fresh interpreters (no forked Pinocchio/MuJoCo/BLAS state), same on every OS
    with ProcessPoolExecutor(max_workers=workers, mp_context=get_context("spawn")) as pool:
        with single_threaded_children():  # the workers start at the first submissions
            futures = [pool.submit(job, c) for c in cases]
        try:
            for fut in as_completed(futures):
                on_done(fut.result())
        except BrokenProcessPool as exc:
            raise ConfigurationError(
                f"a worker process of the pool died ({exc}). Called from a script? The workers "
                "are started with 'spawn', which re-imports the main module: put the call under "
                "\"if __name__ == '__main__':\" (or use workers=1)"
            ) from None
        except BaseException:
            for fut in futures:
                fut.cancel()
            pool.shutdown(wait=False, cancel_futures=True)
            raise


def _dask():
    try:
        import dask.distributed as distributed
    except ImportError as exc:
        raise ConfigurationError(
            f"a Dask scheduler needs Dask distributed ({exc}); install it with "
            "'pip install \"dqcontrol[dask]\"'"
        ) from None
    return distributed


@contextmanager
def _client(executor: Executor, connect_timeout_s: float):
    distributed = _dask()
    if executor.scheduler == LOCAL_SCHEDULER:
        with single_threaded_children():
            cluster = distributed.LocalCluster(
                n_workers=executor.workers,
                threads_per_worker=1,
                processes=True,
                dashboard_address=None,
                silence_logs=logging.ERROR,
            )
        with cluster, distributed.Client(cluster) as client:
            yield client
        return
    try:
        client = distributed.Client(executor.scheduler, timeout=connect_timeout_s)
    except OSError as exc:
        raise ConfigurationError(
            f"cannot connect to the Dask scheduler at {executor.scheduler!r}: {exc}"
        ) from None
    with client:
        yield client


def _run_dask(job, cases, executor: Executor, on_done, connect_timeout_s: float) -> None:
    distributed = _dask()
    with _client(executor, connect_timeout_s) as client:
        token = uuid.uuid4().hex[:12]
        futures = client.map(
            job, list(cases), pure=False, key=[f"case-{i}-{token}" for i in range(len(cases))]
        )
        try:
            for fut in distributed.as_completed(futures):
                on_done(fut.result())
        except BaseException:
            client.cancel(futures)
            raise
