"""The camera-operator policy at the service's edge: degrees, the 422 on a bad value, storage.

The engine's :class:`~tracker.audio.policy.CameraPolicy` keeps angles in radians; here a
``*_rad`` field is shown and taken as ``*_deg`` (``deadband_deg``). Where the policy comes from,
lowest first: the trackers' defaults, the ``camera_policy`` setting (config file table
``[camera_policy]`` or ``TRACKER_CAMERA_POLICY`` as JSON), what an engineer stored through the
API (kept in the database, restored at start). DELETE on the API forgets the stored values.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping
from typing import Any

from tracker.audio.policy import POLICY_FIELDS, CameraPolicy, PolicyField
from tracker.errors import ConfigError, OutOfRange

STORE_KEY = "camera_policy"


def public_name(f: PolicyField) -> str:
    """The field's name on the API: ``deadband_rad`` -> ``deadband_deg``."""
    return f.name[: -len("_rad")] + "_deg" if f.unit == "rad" else f.name


_BY_PUBLIC: dict[str, PolicyField] = {public_name(f): f for f in POLICY_FIELDS}
PUBLIC_NAMES: tuple[str, ...] = tuple(_BY_PUBLIC)


def _shown(f: PolicyField, value: float) -> float:
    """An engine value in the API's unit (degrees for angles, rounded away from float noise)."""
    if f.unit == "rad":
        return round(math.degrees(value), 6)
    return int(value) if f.unit == "count" else float(value)


def policy_to_json(policy: CameraPolicy) -> dict[str, float]:
    """API name -> value (seconds, degrees, counts)."""
    return {public_name(f): _shown(f, getattr(policy, f.name)) for f in POLICY_FIELDS}


def fields_json() -> list[dict[str, Any]]:
    """The catalogue for the console: name, unit, allowed range, default and meaning."""
    default = CameraPolicy()
    out = []
    for f in POLICY_FIELDS:
        unit = "deg" if f.unit == "rad" else f.unit
        out.append({"name": public_name(f), "unit": unit, "min": _shown(f, f.low),
                    "max": _shown(f, f.high), "default": _shown(f, getattr(default, f.name)),
                    "meaning": f.meaning})
    return out


def describe_range_public(f: dict[str, Any]) -> str:
    """A catalogue entry's range in words (API units): "0-30 s", "0-30°", "whole numbers 2-50"."""
    if f["unit"] == "count":
        return f"whole numbers {f['min']:g}-{f['max']:g}"
    unit = "°" if f["unit"] == "deg" else f" {f['unit']}"
    return f"{f['min']:g}-{f['max']:g}{unit}"


def policy_from_json(values: Mapping[str, object], base: CameraPolicy | None = None,
                     where: str = "camera policy") -> CameraPolicy:
    """``base`` (the defaults when None) with ``values`` (API names and units) applied.

    Raises
    ------
    ConfigError
        An unknown name (the message lists the known ones).
    OutOfRange
        A value that is not a number, or is outside its range: ``name`` is the API name, the
        message and ``low``/``high`` are in the API's unit.
    """
    base = base if base is not None else CameraPolicy()
    unknown = sorted(set(values) - set(_BY_PUBLIC))
    if unknown:
        raise ConfigError(f"{where}: unknown setting(s) {', '.join(unknown)}; "
                          f"settings: {', '.join(PUBLIC_NAMES)}")
    changes: dict[str, object] = {}
    for name, value in values.items():
        f = _BY_PUBLIC[name]
        number = value
        if f.unit == "rad" and isinstance(value, int | float) and not isinstance(value, bool):
            try:
                number = math.radians(value)
            except OverflowError:  # an integer past float's range: refused below as it is
                number = value
        try:
            changes[f.name] = number
            base.replaced({f.name: number}, where)
        except OutOfRange:
            lo, hi = _shown(f, f.low), _shown(f, f.high)
            unit = "°" if f.unit == "rad" else (" s" if f.unit == "s" else "")
            kind = "a whole number " if f.unit == "count" else ""
            raise OutOfRange(f"{where}: {name}={value!r} must be {kind}within {lo:g}-{hi:g}{unit} "
                             f"({f.meaning})", name, value, lo, hi,
                             "deg" if f.unit == "rad" else f.unit) from None
    return base.replaced(changes, where)


# -- storage: one small pair of functions, to move to the shared settings store in one place --

def load_stored(db: Any) -> dict[str, object] | None:  # noqa: ANN401 - app.db.Database
    """The values an engineer stored (API names), or None."""
    stored = db.get_value(STORE_KEY)
    return dict(stored) if stored is not None else None


def store(db: Any, values: Mapping[str, object] | None) -> None:  # noqa: ANN401
    """Keep ``values`` (API names) in one transaction, or forget them (None)."""
    if values is None:
        db.delete_value(STORE_KEY)
    else:
        db.put_value(STORE_KEY, dict(values))


class PolicyHolder:
    """The room's policy in force, where it came from, and who is told when it changes.

    ``listeners`` are called with the new :class:`CameraPolicy` (the audio stream's
    ``set_policy``: applied from its next frame, no restart).
    """

    def __init__(self, configured: Mapping[str, object], db: Any) -> None:  # noqa: ANN401
        self._configured = dict(configured)
        self._db = db
        self.base = policy_from_json(self._configured, where="setting 'camera_policy'")
        self.policy, self.source = self.base, "config" if self._configured else "default"
        self.listeners: list[Any] = []
        stored = load_stored(db)
        if stored:
            try:
                self.policy, self.source = policy_from_json(stored, self.base,
                                                            where="stored camera policy"), "stored"
            except ConfigError as exc:  # bounds changed since: the service still starts
                logging.getLogger("app.policy").error("stored camera policy ignored: %s", exc)

    def update(self, changes: Mapping[str, object]) -> CameraPolicy:
        """Apply and store ``changes`` (API names and units) over the policy in force; nothing
        changes when one of them is refused (ConfigError / OutOfRange)."""
        policy = policy_from_json(changes, self.policy)
        stored = {**(load_stored(self._db) or {}), **changes}
        store(self._db, stored)
        self._set(policy, "stored")
        return policy

    def reset(self) -> CameraPolicy:
        """Forget the stored values: back to the config file's policy (or the defaults)."""
        store(self._db, None)
        self._set(self.base, "config" if self._configured else "default")
        return self.base

    def _set(self, policy: CameraPolicy, source: str) -> None:
        self.policy, self.source = policy, source
        for listener in self.listeners:
            listener(policy)
