"""``dqcontrol bench``: control-step and kinematics timings with peer ratios.

The benchmark's code is not part of the package: it is ``benchmarks/bench.py`` of the
source repository, loaded from the folder beside the package (an editable install of a
checkout). An installed wheel has no such folder, and the command says so.
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
from pathlib import Path
from types import ModuleType

from dqcontrol.cli.common import NO_BARS_HELP, add_out_option, add_progress_option

__all__ = ["bench_path", "load_bench", "register"]

#: The module's name once loaded (``sys.modules``).
_MODULE = "dqcontrol_benchmarks_bench"


def bench_path() -> Path:
    """Where the repository's ``benchmarks/bench.py`` is, beside the package's folder."""
    import dqcontrol

    return Path(dqcontrol.__file__).resolve().parents[1] / "benchmarks" / "bench.py"


def load_bench() -> ModuleType:
    """The benchmark module ``benchmarks/bench.py`` of the source checkout.

    Raises:
        ConfigurationError: there is no source checkout beside the package (an installed
            wheel): ``dqcontrol bench`` needs one.
    """
    from dqcontrol.errors import ConfigurationError

    module = sys.modules.get(_MODULE)
    if module is not None:
        return module
    path = bench_path()
    if not path.is_file():
        raise ConfigurationError(
            f"'dqcontrol bench' needs a source checkout of dqcontrol: the benchmark is "
            f"benchmarks/bench.py of the repository, and there is none at {path} (this "
            "dqcontrol is an installed package). Clone the repository and install it with "
            "'pip install -e .', or run 'python benchmarks/bench.py' there."
        )
    spec = importlib.util.spec_from_file_location(_MODULE, path)
    if spec is None or spec.loader is None:
        raise ConfigurationError(f"cannot load {path} as a Python module")
    module = importlib.util.module_from_spec(spec)
    sys.modules[_MODULE] = module
    try:
        spec.loader.exec_module(module)
    except BaseException:
        del sys.modules[_MODULE]
        raise
    return module


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``bench`` subcommand to ``subparsers``."""
    parser = subparsers.add_parser(
        "bench",
        help="time the control step of every controller and the kinematics (needs a source "
        "checkout)",
        description="Every performance figure at T = 1 ms on the LBR4p: the median and "
        "99th-percentile step times of the local, predictive (p = 6, 10) and proportional "
        "controllers on both QP backends, the backends' agreement, kinematics, ratios "
        "against DQ Robotics measured in the same run (if installed), the MuJoCo closed "
        "loop's real-time factor (p = 10, T = 1 ms, 2 s circle), and the step time against "
        "p and the joint count. Each target is printed as met or not met; the figures and "
        "the machine go to a JSON file (about a minute; --quick: seconds). The benchmark is "
        "benchmarks/bench.py of the source repository: this command needs a checkout "
        "(an editable install), not an installed wheel.",
    )
    add_out_option(parser, "results/bench.json", "JSON output file", metavar="FILE")
    add_progress_option(parser, NO_BARS_HELP)
    parser.add_argument(
        "--quick",
        action="store_true",
        help="few steps and a reduced sweep (seconds; indicative figures only)",
    )
    parser.set_defaults(func=_run)


def _run(args: argparse.Namespace) -> int:
    load_bench().main(out=args.out, quick=args.quick)
    return 0
