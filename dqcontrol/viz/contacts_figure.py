"""The contacts figure of a run: the closest distance over time and the contacts found at
each sample, titled with the run's counts, deepest penetration and closest pair.

Drawn from a :class:`~dqcontrol.runs.contacts.RunContacts` with its per-sample columns
(a run saved by ``dqcontrol run`` with obstacles or self-collision, see docs/run_logs.md);
``dqcontrol view --figures`` writes it as ``<name>_contacts.<fmt>``. Only matplotlib's
object-oriented API is used (no ``pyplot``).
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from dqcontrol.errors import ParameterError
from dqcontrol.extras import missing_extra
from dqcontrol.runs.contacts import RunContacts
from dqcontrol.runs.storage import atomic_write_bytes

try:
    from matplotlib.figure import Figure
    from matplotlib.ticker import MaxNLocator
except ImportError as exc:
    raise missing_extra(
        "matplotlib", extra="viz", purpose="dqcontrol.viz.contacts_figure", reason=str(exc)
    ) from None

__all__ = ["contacts_figure", "plot_contacts"]


def contacts_figure(
    contacts: RunContacts, t_s: np.ndarray, safety_distance_m: float | None = None
) -> Figure:
    """The figure: the closest distance [mm] against time ``t_s`` [s] (with the safety
    distance dashed, if given), and the robot–obstacle and self contacts per sample.

    Raises:
        ParameterError: ``contacts`` has no per-sample columns, or not one per time.
    """
    columns = contacts.per_sample
    if columns is None:
        raise ParameterError("the run's contacts have no per-sample columns to draw")
    t = np.asarray(t_s, dtype=float)
    if any(len(v) != t.size for v in columns.values()):
        raise ParameterError(
            f"contacts per sample ({len(columns['contacts_closest_m'])}) do not match the "
            f"run's {t.size} sample times"
        )
    fig = Figure(figsize=(6.4, 4.4), layout="constrained")
    ax_d, ax_c = fig.subplots(2, 1, sharex=True)
    ax_d.plot(t, 1e3 * columns["contacts_closest_m"], color="C0", label="closest distance")
    if safety_distance_m is not None:
        ax_d.axhline(1e3 * safety_distance_m, color="0.15", linestyle="--", label="safety")
    ax_d.axhline(0.0, color="C3", linewidth=0.8)
    ax_d.set_ylabel("distance [mm]")
    ax_d.grid(True, alpha=0.3)
    ax_d.legend(loc="best", fontsize="small")
    ax_c.step(t, columns["contacts_obstacle"], where="post", color="C3", label="robot-obstacle")
    ax_c.step(t, columns["contacts_self"], where="post", color="C1", label="self")
    ax_c.set_xlabel("t [s]")
    ax_c.set_ylabel("contacts")
    ax_c.set_ylim(bottom=0.0)
    ax_c.yaxis.set_major_locator(MaxNLocator(integer=True))
    ax_c.grid(True, alpha=0.3)
    ax_c.legend(loc="best", fontsize="small")
    ax_d.set_title(_title(contacts), fontsize="small")
    return fig


def _title(contacts: RunContacts) -> str:
    """Counts, deepest penetration and the closest pair, on two lines."""
    obstacle = f"robot-obstacle {contacts.obstacle.count}" if contacts.obstacles else "no obstacles"
    first = (
        f"contacts: {obstacle}, self {contacts.self_contact.count}, deepest "
        f"{1e3 * contacts.deepest_m:.1f} mm"
    )
    if contacts.closest_m is None:
        return f"{first}\nno collision pair"
    a, b = contacts.closest_links or ("?", "?")
    return f"{first}\nclosest {1e3 * contacts.closest_m:.1f} mm: {a}–{b}"


def plot_contacts(
    contacts: RunContacts,
    t_s: np.ndarray,
    path: str | Path,
    *,
    safety_distance_m: float | None = None,
    dpi: float = 110.0,
) -> Path:
    """Write :func:`contacts_figure` to ``path`` (its suffix: ``.png`` or ``.svg``),
    atomically; returns ``path``."""
    target = Path(path)
    buffer = io.BytesIO()
    figure = contacts_figure(contacts, t_s, safety_distance_m)
    figure.savefig(buffer, format=target.suffix[1:], dpi=dpi)
    return atomic_write_bytes(target, buffer.getvalue())
