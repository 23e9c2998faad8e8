"""Running a study: its cases swept on the shared executor
(:func:`~dqcontrol.experiments.sweep.sweep`), each case's result saved as it arrives, and
the tables at the end.

Every finished case is written at once to ``<folder>/<name>_cases/<case>.json``, atomically
(:func:`~dqcontrol.runs.storage.atomic_write_text`): a crash or Ctrl-C loses no case that
had finished. The tables (``<folder>/<name>.md`` and ``.csv``, as the study's ``formats``
say) are written atomically at the end, also after an interrupt (with the cases that
completed, marked as such).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from dqcontrol.experiments.executor import resolve_executor
from dqcontrol.experiments.sweep import sweep
from dqcontrol.runs.storage import atomic_write_text, jsonable
from dqcontrol.studies.kinds import RunInfo, experiment_kind
from dqcontrol.studies.spec import Study

__all__ = ["StudyResult", "run_study", "study_cases"]


@dataclass
class StudyResult:
    """What :func:`run_study` produced.

    Attributes:
        study: the study.
        results: each finished case's result, in case order (the experiment's own form).
        records: the same as plain JSON data (the case files' content).
        indices: their indices in :func:`study_cases`.
        files: the tables written, by format.
        cases_dir: the folder of the case files.
        wall_time_s: wall time of the cases [s].
        executor: where they ran.
        total_cases: the cases of the grid.
        interrupted: whether Ctrl-C stopped the study before every case finished.
        texts: the tables' text, by format (every format, written or not).
    """

    study: Study
    results: list[Any]
    records: list[dict]
    indices: list[int]
    files: dict[str, Path]
    cases_dir: Path
    wall_time_s: float
    executor: str
    total_cases: int
    interrupted: bool = False
    texts: dict[str, str] = field(default_factory=dict)


def study_cases(study: Study) -> list:
    """The study's cases, in the table's order (the experiment's case objects)."""
    return experiment_kind(study.experiment).cases(study)


def run_study(
    study: Study,
    *,
    out: str | os.PathLike | None = None,
    workers: int | None = None,
    scheduler: str | None = None,
    progress: bool = True,
    command: str | None = None,
) -> StudyResult:
    """Run every case of ``study`` and write its results.

    Args:
        study: the study (:func:`~dqcontrol.studies.load_study`).
        out: results folder (default: the study's ``[output] folder``).
        workers: processes of the local pool (default: all cores; 1 runs in this process).
        scheduler: a Dask scheduler address, or ``"local"`` for a local Dask cluster of
            ``workers`` single-threaded processes (:mod:`dqcontrol.experiments.executor`).
        progress: show a progress bar (tqdm, on stderr).
        command: the command line, quoted in the report.

    Ctrl-C stops the study: the cases that finished are in their files and in the tables,
    and :attr:`StudyResult.interrupted` is set.

    The pool's workers are started with ``spawn``: a script that calls this function must
    do so under ``if __name__ == "__main__":``.
    """
    kind = experiment_kind(study.experiment)
    cases = kind.cases(study)
    folder = Path(study.output.folder if out is None else out)
    cases_dir = folder / f"{study.name}_cases"
    cases_dir.mkdir(parents=True, exist_ok=True)
    runs_dir = folder / f"{study.name}_runs" if study.output.save_runs else None
    save_dir = None if runs_dir is None else str(runs_dir.resolve())
    executor = resolve_executor(workers, scheduler, len(cases))
    job = kind.job(study, save_dir)
    outcome = _sweep_cases(study, job, cases, executor, cases_dir, progress)
    wall, interrupted = outcome.wall_time_s, outcome.interrupted
    finished = outcome.results
    info = RunInfo(
        wall, executor.label, command or f"dqcontrol study {study.source}", interrupted, len(cases)
    )
    texts = kind.render(study, finished, info)
    files = _write_tables(study, folder, texts)
    return StudyResult(
        study=study,
        results=finished,
        records=[jsonable(kind.record(r)) for r in finished],
        indices=outcome.indices,
        files=files,
        cases_dir=cases_dir,
        wall_time_s=wall,
        executor=executor.label,
        total_cases=len(cases),
        interrupted=interrupted,
        texts=texts,
    )


def _write_tables(study: Study, folder: Path, texts: dict) -> dict:
    """Write the study's tables in its output formats, atomically; ``{format: path}``."""
    suffix = {"md": ".md", "csv": ".csv"}
    return {
        fmt: atomic_write_text(folder / f"{study.name}{suffix[fmt]}", texts[fmt])
        for fmt in study.output.formats
    }


def _sweep_cases(study: Study, job, cases, executor, cases_dir: Path, progress: bool):
    """Run the cases, the costliest first, each one's record saved in ``cases_dir``."""
    kind = experiment_kind(study.experiment)
    return sweep(
        job,
        cases,
        executor,
        order=sorted(range(len(cases)), key=lambda i: -kind.cost(cases[i])),
        name=kind.case_name,
        progress=study.name if progress else None,
        record=kind.record,
        record_dir=cases_dir,
    )
