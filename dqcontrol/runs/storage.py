"""Saving and loading runs: a ``.npz`` of the log arrays and a ``.json`` of the rest.

Every file is written atomically: the bytes go to a temporary file in the target's own
folder (same file system), which is flushed, ``fsync``-ed and then renamed over the target
with :func:`os.replace`. A crash, a full disk or Ctrl-C in the middle of a write therefore
leaves either the previous file or the new one, never half a file, and the temporary file is
removed on any exception.

A run ``name`` in ``folder`` is two files:

* ``name.npz`` — :meth:`RunLog.arrays` (``np.savez_compressed``, loadable without pickle);
* ``name.json`` — ``{"format", "version", "name", "npz", "meta", "metrics", "interrupted",
  "note", "contacts"}``. Written after the ``.npz``, so a ``.json`` on disk always has its
  arrays. ``"contacts"`` is the run's :class:`~dqcontrol.runs.contacts.RunContacts`
  (``{"checked": false}`` when they were not measured), whose per-sample columns
  (:data:`~dqcontrol.runs.contacts.CONTACT_COLUMNS`) go in the ``.npz``; a file saved
  before contacts were recorded has neither and loads as before.
  Non-finite floats (e.g. the peak torque of a kinematic run, NaN) are stored as ``null``
  (strict JSON, readable by any tool) and come back as ``None``.
"""

from __future__ import annotations

import io
import json
import math
import os
import secrets
from pathlib import Path
from typing import Any

import numpy as np

from dqcontrol.errors import ParameterError
from dqcontrol.runs.contacts import CONTACT_COLUMNS
from dqcontrol.runs.log import RunLog

__all__ = [
    "RUN_FORMAT",
    "atomic_write_bytes",
    "atomic_write_text",
    "jsonable",
    "load_run",
    "run_file",
    "run_paths",
    "save_run",
]

#: Value of the ``"format"`` key of a run's ``.json``.
RUN_FORMAT = "dqcontrol-run"
_VERSION = 1


def _fsync_dir(folder: Path) -> None:
    """Make a rename in ``folder`` durable (POSIX; silently skipped where unsupported)."""
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:  # pragma: no cover - e.g. Windows cannot open a directory
        return
    try:
        os.fsync(fd)
    except OSError:  # pragma: no cover
        pass
    finally:
        os.close(fd)


def _create_temporary(folder: Path, name: str) -> tuple[int, str]:
    """A new temporary file beside ``name`` in ``folder``, opened for writing, with the
    permissions of a normally created file: ``0o666`` less the umask, applied by the
    kernel at creation (the process-wide umask is never read or changed, so threads that
    create files at the same time are not affected)."""
    flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_CLOEXEC", 0)
    for _ in range(100):
        tmp = folder / f".{name}.{secrets.token_hex(6)}.tmp"
        try:
            return os.open(tmp, flags, 0o666), str(tmp)
        except FileExistsError:
            continue
    raise FileExistsError(f"no free temporary name for {name!r} in {folder}")


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (temporary file, fsync, ``os.replace``).

    The parent folder is created if needed. Returns the path written.
    """
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp_name = _create_temporary(target.parent, target.name)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp_name, target)
    except BaseException:
        try:
            os.unlink(tmp_name)
        except FileNotFoundError:
            pass
        raise
    _fsync_dir(target.parent)
    return target


def atomic_write_text(path: str | os.PathLike, text: str, encoding: str = "utf-8") -> Path:
    """Write ``text`` to ``path`` atomically (see :func:`atomic_write_bytes`)."""
    return atomic_write_bytes(path, text.encode(encoding))


def jsonable(value):
    """``value`` as strict-JSON data: numpy scalars/arrays to Python, non-finite to None."""
    if isinstance(value, dict):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return jsonable(value.tolist())
    if isinstance(value, np.generic):
        return jsonable(value.item())
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, Path):
        return str(value)
    if value is None or isinstance(value, bool | int | float | str):
        return value
    return repr(value)


def _check_name(name: str) -> str:
    if not isinstance(name, str) or not name or name in (".", ".."):
        raise ParameterError(f"run name must be a non-empty string, got {name!r}")
    if "/" in name or "\\" in name or os.sep in name:
        raise ParameterError(f"run name must not contain a path separator, got {name!r}")
    return name


def save_run(result, folder: str | os.PathLike, name: str) -> tuple[Path, ...]:
    """Save a :class:`~dqcontrol.sim.kinematic.RunResult` as ``folder/name.npz`` + ``.json``.

    Both files are written atomically (the ``.npz`` first). Existing files of the same name
    are replaced. Returns ``(npz_path, json_path)``. A streamed run (``result.log_file``)
    is named in the ``.json`` (``"log"``); if ``result.log`` holds only every k-th of its
    samples (``result.log_stride > 1``) no ``.npz`` is written: ``(json_path,)``.
    """
    name = _check_name(name)
    folder = Path(folder)
    log: RunLog = result.log
    streamed = getattr(result, "log_file", None)
    contacts = getattr(result, "contacts", None)
    written: list[Path] = []
    if getattr(result, "log_stride", 1) == 1:
        buffer = io.BytesIO()
        arrays: dict[str, Any] = log.arrays()  # as keywords, which numpy's stubs type narrowly
        arrays.update(_contact_columns(contacts, len(log)))
        np.savez_compressed(buffer, **arrays)
        written.append(atomic_write_bytes(folder / f"{name}.npz", buffer.getvalue()))
    record = {
        "format": RUN_FORMAT,
        "version": _VERSION,
        "name": name,
        "npz": written[0].name if written else None,
        "meta": jsonable(log.meta),
        "metrics": jsonable(result.metrics.as_dict()),
        "interrupted": bool(result.interrupted),
        "note": str(result.note),
        "contacts": jsonable(contacts.as_record()) if contacts else {"checked": False},
    }
    if contacts and not (written and _contact_columns(contacts, len(log))):
        record["contacts"]["per_sample"] = None
    if streamed is not None:
        log_path = Path(streamed)
        same = log_path.parent.resolve() == folder.resolve()
        record["log"] = log_path.name if same else str(log_path.resolve())
    text = json.dumps(record, indent=2, allow_nan=False) + "\n"
    return (*written, atomic_write_text(folder / f"{name}.json", text))


def run_paths(path: str | os.PathLike) -> tuple[Path, Path, Path]:
    """``(json, npz, mcap)`` paths of the run at ``path`` (its ``.json``, ``.npz``,
    ``.mcap`` or their common stem); none of them need exist."""
    p = Path(path)
    stem = p.with_suffix("") if p.suffix in (".json", ".npz", ".mcap") else p
    return tuple(stem.with_name(stem.name + ext) for ext in (".json", ".npz", ".mcap"))  # type: ignore[return-value]


def run_file(path: str | os.PathLike) -> Path:
    """The file that holds the run at ``path``: its ``.json``, unless ``path`` is an
    ``.mcap`` or the stem's ``.mcap`` is newer than its ``.json`` (or has none): a streamed
    run that has not ended, never mistaken for an earlier run saved under the same name."""
    json_path, _npz, mcap_path = run_paths(path)
    if Path(path).suffix == ".mcap" or not json_path.is_file():
        return mcap_path if mcap_path.is_file() or not json_path.exists() else json_path
    if mcap_path.is_file() and mcap_path.stat().st_mtime_ns > json_path.stat().st_mtime_ns:
        return mcap_path
    return json_path


def load_run(path: str | os.PathLike, max_samples: int | None = None) -> tuple[RunLog, dict]:
    """Load a run saved by :func:`save_run` or streamed by a loop (``.mcap``).

    ``path`` is the ``.json``, the ``.npz``, the ``.mcap`` or their common stem
    (:func:`run_file` says which is read). A ``.json`` is read with its arrays (``npz``,
    else its streamed ``log``), an ``.mcap`` alone
    (:func:`~dqcontrol.runs.streamed_run.load_streamed`). Returns the
    :class:`RunLog` (with its ``meta``) and the run record (``meta``, ``metrics``,
    ``interrupted``, ``note``, ``contacts`` when saved with them, and their per-sample
    columns from the ``.npz`` as ``contact_columns`` …; for a streamed run also
    ``complete``: ``False`` when the file was cut short).
    :func:`~dqcontrol.runs.contacts.loaded_contacts` reads the contacts of a record.

    Args:
        path: the run.
        max_samples: a streamed run keeps every k-th sample so that at most this many
            are loaded (for display); ``None`` (and any ``.npz`` run): all of them.

    Raises:
        FileNotFoundError: no such run.
        ParameterError: the file is not a dqcontrol run.
    """
    from dqcontrol.runs.streamed_run import load_streamed

    json_path = run_file(path)
    if json_path.suffix == ".mcap":
        return load_streamed(json_path, max_samples)
    record = json.loads(json_path.read_text(encoding="utf-8"))
    if not isinstance(record, dict) or record.get("format") != RUN_FORMAT:
        raise ParameterError(f"{json_path} is not a dqcontrol run file (format {RUN_FORMAT!r})")
    if not record.get("npz") and record.get("log"):
        log, streamed = load_streamed(json_path.parent / record["log"], max_samples)
        return log, {**streamed, **record, "complete": streamed["complete"]}
    npz_path = json_path.with_name(record.get("npz") or json_path.stem + ".npz")
    with np.load(npz_path, allow_pickle=False) as data:
        arrays = {k: data[k] for k in data.files}
    log = RunLog.from_arrays(arrays, record.get("meta") or {})
    columns = {k: arrays[k] for k in CONTACT_COLUMNS if k in arrays}
    if columns:
        record["contact_columns"] = columns
    return log, record


def _contact_columns(contacts, samples: int) -> dict[str, np.ndarray]:
    """The per-sample contact columns to store in the ``.npz``: those of ``contacts`` when
    they cover the log's ``samples``, else none."""
    per_sample = getattr(contacts, "per_sample", None)
    if not per_sample or any(len(per_sample[k]) != samples for k in CONTACT_COLUMNS):
        return {}
    return {k: np.asarray(per_sample[k]) for k in CONTACT_COLUMNS}
