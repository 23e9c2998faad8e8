"""The contacts of a run, as saved with it: robot–obstacle and self contacts, the closest
distance and its pair, over the run's samples and per sample.

:func:`~dqcontrol.sim.run_contacts.measure_contacts` computes a :class:`RunContacts` from a
run's joint positions; :func:`~dqcontrol.runs.storage.save_run` stores it in the run's
``.json`` (key ``"contacts"``, :meth:`RunContacts.as_record`) and its per-sample columns in
the ``.npz`` (:data:`CONTACT_COLUMNS`); :func:`~dqcontrol.runs.storage.load_run` reads them
back and :func:`contacts_text` says what a saved run holds, also for a run saved before
contacts were recorded ("not recorded").

A contact count is the number of (contact, sample) pairs over the samples checked, as
MuJoCo finds them with the arm set at each sample's joint positions (``mj_forward``, no
dynamics); a penetration depth is positive [m]. The closest distance is the smallest signed
distance of the collision model's pairs (docs/theory.md §10) over the samples [m]; negative
when two shapes overlap.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["CONTACT_COLUMNS", "ContactKind", "RunContacts", "contacts_text", "loaded_contacts"]

#: The per-sample columns in a run's ``.npz``: the closest distance [m] (``inf`` without a
#: pair), the robot–obstacle and self contacts found, and the deepest penetration [m] (0
#: without contact).
CONTACT_COLUMNS = ("contacts_closest_m", "contacts_obstacle", "contacts_self", "contacts_depth_m")


@dataclass(frozen=True)
class ContactKind:
    """Contacts of one kind (robot–obstacle or self) over a run.

    Attributes:
        count: contacts summed over the samples checked.
        samples: samples with at least one such contact.
        deepest_m: the deepest penetration [m] (0 without contact).
    """

    count: int = 0
    samples: int = 0
    deepest_m: float = 0.0

    def as_record(self) -> dict:
        """The JSON form: ``{"count", "samples", "deepest_m"}``."""
        return {"count": self.count, "samples": self.samples, "deepest_m": self.deepest_m}

    @classmethod
    def from_record(cls, record: dict) -> ContactKind:
        """Rebuild from :meth:`as_record`."""
        return cls(int(record["count"]), int(record["samples"]), float(record["deepest_m"]))


@dataclass(frozen=True)
class RunContacts:
    """What a run came into contact with, and how close it came.

    Attributes:
        obstacles: the names of the run's obstacles (empty: no obstacles).
        self_collision: whether the run's collision model held the robot's own pairs.
        samples: the samples checked (the run's, or every k-th of a long streamed run).
        obstacle: robot–obstacle contacts. self_contact: contacts between two robot geoms.
        closest_m: the smallest distance over the collision model's pairs and the samples
            [m]; ``None`` when the model has no pair.
        closest_pair: the two geometries of that distance (robot geometry first).
        closest_links: their links (the obstacle's name for an obstacle).
        closest_t_s: the time of the sample where it occurred [s].
        per_sample: :data:`CONTACT_COLUMNS` over the samples checked (``None``: not kept).
    """

    obstacles: tuple[str, ...]
    self_collision: bool
    samples: int
    obstacle: ContactKind
    self_contact: ContactKind
    closest_m: float | None
    closest_pair: tuple[str, str] | None
    closest_links: tuple[str, str] | None
    closest_t_s: float | None
    per_sample: dict[str, np.ndarray] | None = field(default=None, compare=False)

    @property
    def deepest_m(self) -> float:
        """The deepest penetration of either kind [m]."""
        return max(self.obstacle.deepest_m, self.self_contact.deepest_m)

    def as_record(self) -> dict:
        """The JSON form stored under ``"contacts"`` in a run's ``.json``."""
        closest = None
        if self.closest_m is not None:
            closest = {
                "distance_m": self.closest_m,
                "pair": list(self.closest_pair or ()),
                "links": list(self.closest_links or ()),
                "t_s": self.closest_t_s,
            }
        return {
            "checked": True,
            "obstacles": list(self.obstacles),
            "self_collision": self.self_collision,
            "samples": self.samples,
            "robot_obstacle": self.obstacle.as_record(),
            "self": self.self_contact.as_record(),
            "closest": closest,
            "per_sample": list(CONTACT_COLUMNS) if self.per_sample is not None else None,
        }

    @classmethod
    def from_record(
        cls, record: dict, columns: dict[str, np.ndarray] | None = None
    ) -> RunContacts | None:
        """Rebuild from :meth:`as_record` (and the ``.npz``'s columns); ``None`` for a run
        whose contacts were not checked (``{"checked": false}``)."""
        if not record.get("checked"):
            return None
        closest = record.get("closest") or {}
        pair = closest.get("pair")
        links = closest.get("links")
        per_sample = None
        if columns is not None and all(k in columns for k in CONTACT_COLUMNS):
            per_sample = {k: columns[k] for k in CONTACT_COLUMNS}
        return cls(
            obstacles=tuple(record.get("obstacles") or ()),
            self_collision=bool(record.get("self_collision")),
            samples=int(record.get("samples") or 0),
            obstacle=ContactKind.from_record(record["robot_obstacle"]),
            self_contact=ContactKind.from_record(record["self"]),
            closest_m=_float_or_none(closest.get("distance_m")),
            closest_pair=(str(pair[0]), str(pair[1])) if pair else None,
            closest_links=(str(links[0]), str(links[1])) if links else None,
            closest_t_s=_float_or_none(closest.get("t_s")),
            per_sample=per_sample,
        )

    def summary(self) -> str:
        """One line: the closest distance, the contacts of each kind, the closest pair."""
        obstacle = f"robot-obstacle {self.obstacle.count}" if self.obstacles else "no obstacles"
        contacts = (
            f"contacts {obstacle}, self {self.self_contact.count}, deepest "
            f"{1e3 * self.deepest_m:.1f} mm"
        )
        if self.closest_m is None:
            return f"min distance - (no collision pair); {contacts} ({self.samples} samples)"
        links = self.closest_links or ("?", "?")
        return (
            f"min distance {1e3 * self.closest_m:.1f} mm; {contacts}; closest pair "
            f"{links[0]}–{links[1]} at t = {self.closest_t_s:.3f} s ({self.samples} samples)"
        )


def _float_or_none(value) -> float | None:
    return None if value is None else float(value)


def loaded_contacts(record: dict) -> RunContacts | None:
    """The contacts of a run record loaded by :func:`~dqcontrol.runs.storage.load_run`, with
    their per-sample columns when its ``.npz`` has them; ``None`` when the record has none
    (not measured, or saved before contacts were recorded: see :func:`contacts_text`)."""
    stored = record.get("contacts")
    if not isinstance(stored, dict):
        return None
    return RunContacts.from_record(stored, record.get("contact_columns"))


def contacts_text(record: dict) -> str:
    """What a loaded run record (:func:`~dqcontrol.runs.storage.load_run`) says about its
    contacts, as one line for ``dqcontrol view``."""
    if not isinstance(record.get("contacts"), dict):
        return "contacts: not recorded (saved without contacts, or a streamed log alone)"
    contacts = loaded_contacts(record)
    if contacts is None:
        return "contacts: not checked (no obstacles, no self-collision check)"
    return "contacts: " + contacts.summary()
