"""Localizers chosen by name: ``make_localizer("srp_phat", array, fs_hz)``.

=========  ==================================================================================
seed_rms   the seed's running-RMS peak timing (baseline to beat, not a default)
gcc_phat   GCC-PHAT per pair, sub-sample peaks within d/c, least-squares direction
srp_phat   SRP-PHAT over all pairs on an azimuth (and elevation) grid; the default
srp_dpd    SRP-PHAT over direct-path-dominant time-frequency bins only (reverb/noise robust)
=========  ==================================================================================
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from tracker.audio.array import MicArray
from tracker.audio.localizers.base import DirectionEstimate, Localizer
from tracker.audio.localizers.gcc_phat import GccPhat
from tracker.audio.localizers.seed_rms import SeedRms
from tracker.audio.localizers.srp_dpd import SrpDpd
from tracker.audio.localizers.srp_phat import SrpPhat
from tracker.errors import ConfigError

LOCALIZERS: dict[str, Callable[..., Localizer]] = {
    SeedRms.name: SeedRms,
    GccPhat.name: GccPhat,
    SrpPhat.name: SrpPhat,
    SrpDpd.name: SrpDpd,
}
DEFAULT_LOCALIZER = SrpPhat.name


def make_localizer(name: str, array: MicArray, fs_hz: int, **options: Any) -> Localizer:
    """Build the localizer registered as ``name`` for ``array`` at ``fs_hz``."""
    try:
        factory = LOCALIZERS[name]
    except KeyError:
        known = ", ".join(sorted(LOCALIZERS))
        raise ConfigError(f"unknown localizer {name!r}; choose one of: {known}") from None
    return factory(array, fs_hz, **options)


__all__ = ["DEFAULT_LOCALIZER", "LOCALIZERS", "DirectionEstimate", "Localizer", "make_localizer"]
