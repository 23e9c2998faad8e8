"""DAQP, the default backend (docs/theory.md §6, §7.5): :class:`DaqpBackend` and the paths it
specialises on the problem's structure — the block path (:mod:`.blocks`), the
least-distance form (:mod:`.least_distance`), the solve on the last active set
(:mod:`.active_set`, :mod:`.reduced_active_set`, :mod:`.clear_rows`), the factor in the
predicted states (:mod:`.state_factor`), the warm levels (:mod:`.warm_levels`) and the
warm starts carried by row name (:mod:`.row_identity`)."""

from dqcontrol.controllers.backends.daqp.backend import DEFAULT_DAQP_SETTINGS, DaqpBackend

__all__ = ["DEFAULT_DAQP_SETTINGS", "DaqpBackend"]
