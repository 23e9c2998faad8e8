"""Studies: a grid of experiment cases described by a TOML file, run on the local process
pool or a Dask cluster, with each case's result saved as it finishes and a Markdown and CSV
table at the end.

- :mod:`~dqcontrol.studies.spec` — :func:`load_study`: the file, read and checked into a
  :class:`Study` (errors name the key and what would be right);
- :mod:`~dqcontrol.studies.kinds` — the experiments a study can run: ``tracking`` (any
  robot, trajectory and controller), ``table1`` and ``faults`` (the thesis's Table 1 and
  the fault campaign, whose shipped study files are ``table1.toml`` and ``faults.toml``);
- :mod:`~dqcontrol.studies.run` — :func:`run_study` and :func:`study_cases`.
"""

from dqcontrol.studies.reader import StudyFileError
from dqcontrol.studies.run import StudyResult, run_study, study_cases
from dqcontrol.studies.spec import (
    SHIPPED,
    OutputSpec,
    RobotSpec,
    Study,
    TrajectoryEntry,
    load_study,
    parse_study,
    shipped_study_path,
)

__all__ = [
    "SHIPPED",
    "OutputSpec",
    "RobotSpec",
    "Study",
    "StudyFileError",
    "StudyResult",
    "TrajectoryEntry",
    "load_study",
    "parse_study",
    "run_study",
    "shipped_study_path",
    "study_cases",
]
