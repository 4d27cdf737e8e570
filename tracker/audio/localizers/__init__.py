"""Localizers chosen by name: ``make_localizer("srp_phat", array, fs_hz)``.

=========  ==================================================================================
seed_rms   the seed's running-RMS peak timing (baseline to beat, not a default)
gcc_phat   GCC-PHAT per pair, sub-sample peaks within d/c, least-squares direction
srp_phat   SRP-PHAT over all pairs on an azimuth (and elevation) grid; the default
srp_dpd    SRP-PHAT over direct-path-dominant time-frequency bins only (reverb/noise robust)
=========  ==================================================================================

The registry knows each localizer's module and imports it when it is first asked for (the
modules pull in scipy and numba: a command that only lists the names does not pay for them).
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Iterator, Mapping
from typing import Any

from tracker.audio.array import MicArray
from tracker.audio.localizers.base import DirectionEstimate, Localizer
from tracker.errors import ConfigError

LocalizerFactory = Callable[..., Localizer]

# name -> "module:Class"
_ENTRIES = {
    "seed_rms": "tracker.audio.localizers.seed_rms:SeedRms",
    "gcc_phat": "tracker.audio.localizers.gcc_phat:GccPhat",
    "srp_phat": "tracker.audio.localizers.srp_phat:SrpPhat",
    "srp_dpd": "tracker.audio.localizers.srp_dpd:SrpDpd",
}


class _Registry(Mapping[str, LocalizerFactory]):
    """Name -> localizer class, each module imported on first use."""

    def __init__(self, entries: dict[str, str]) -> None:
        self._entries = entries

    def __getitem__(self, name: str) -> LocalizerFactory:
        module, _, attribute = self._entries[name].partition(":")
        factory: LocalizerFactory = getattr(importlib.import_module(module), attribute)
        return factory

    def __iter__(self) -> Iterator[str]:
        return iter(self._entries)

    def __len__(self) -> int:
        return len(self._entries)


LOCALIZERS: Mapping[str, LocalizerFactory] = _Registry(_ENTRIES)
DEFAULT_LOCALIZER = "srp_phat"


def make_localizer(name: str, array: MicArray, fs_hz: int, **options: Any) -> Localizer:
    """Build the localizer registered as ``name`` for ``array`` at ``fs_hz``."""
    if name not in LOCALIZERS:
        known = ", ".join(sorted(LOCALIZERS))
        raise ConfigError(f"unknown localizer {name!r}; choose one of: {known}")
    return LOCALIZERS[name](array, fs_hz, **options)


__all__ = ["DEFAULT_LOCALIZER", "LOCALIZERS", "DirectionEstimate", "Localizer", "make_localizer"]
