"""The console's engine settings kept across restarts: each axis's model and gains, tracking on/off.

What an operator or engineer changes through the API (``PUT /axes/{axis}/model``, ``PUT
/axes/{axis}/gains``, ``PUT /tracking``) is stored in the settings table (app/persist.py) once
the engine has accepted it, and :meth:`ConsoleState.restore` applies it again at start-up,
before the control loop's first tick. Only what was changed is stored: an axis nobody retuned
keeps the design the running version of the service makes, so an upgrade's better defaults
are not hidden behind a copy of the old ones.

Keys (value version 1):

- ``console.model.<axis>``: ``{"model": <model JSON as in a version>, "version_id": int}``.
  A model redesigns the axis's controller, so storing one removes that axis's stored gains
  in the same transaction.
- ``console.gains.<axis>``: ``{"type": "ObserverPdGains", "fields": {...}}``, applied after the
  model (the engine redesigns on a model; gains set later override that design).
- ``console.tracking``: ``{"enabled": bool}``.

At start-up every stored value goes through the checks a new one would meet (the engine's
``set_model`` with its model check, ``set_gains`` with its margins, the drive's faults for
tracking). A value they refuse (e.g. gains under a phase-margin floor raised since) is logged,
left stored, not applied (the default stays) and listed in :attr:`ConsoleState.warnings`,
which ``GET /status`` shows. A model with a belt (``compliance``) cannot be confirmed before
the axis has moved (tracker/model_check.py), so it is not restored: offer it again.
"""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Callable
from functools import partial
from typing import Any

from app.modelio import model_from_json
from app.persist import SettingsStore
from tracker.errors import TrackerError

log = logging.getLogger("app.console_state")

AXES = ("pan", "tilt")
VERSION = 1
TRACKING_KEY = "console.tracking"


def model_key(axis: str) -> str:
    return f"console.model.{axis}"


def gains_key(axis: str) -> str:
    return f"console.gains.{axis}"


def gains_json(gains: Any) -> dict[str, Any]:  # noqa: ANN401 - a gains dataclass
    """A gains dataclass as stored: its type's name and its fields."""
    fields = {f.name: float(getattr(gains, f.name)) for f in dataclasses.fields(gains)}
    return {"type": type(gains).__name__, "fields": fields}


class ConsoleState:
    """Stores and restores the console's engine settings (see the module docstring)."""

    def __init__(self, store: SettingsStore) -> None:
        self.store = store
        self.warnings: list[str] = []
        self.tracking_restored = False  # restore() applied a stored tracking on/off

    # -- after a change the engine accepted ---------------------------------------------------
    def model_changed(self, axis: str, model_json: dict[str, Any], version_id: int | None) -> None:
        """The axis's controller was redesigned on ``model_json``: store it, drop its old gains."""
        value = {"model": model_json, "version_id": version_id}
        self.store.write({model_key(axis): value}, deletes=[gains_key(axis)], version=VERSION)
        self.clear_warnings(model_key(axis), gains_key(axis))

    def gains_changed(self, axis: str, gains: Any) -> None:  # noqa: ANN401 - a gains dataclass
        self.store.write({gains_key(axis): gains_json(gains)}, version=VERSION)
        self.clear_warnings(gains_key(axis))

    def tracking_changed(self, enabled: bool) -> None:
        self.store.write({TRACKING_KEY: {"enabled": bool(enabled)}}, version=VERSION)
        self.clear_warnings(TRACKING_KEY)

    # -- at start-up ------------------------------------------------------------------------
    def restore(self, engine: Any) -> list[str]:  # noqa: ANN401 - the engine
        """Apply what is stored to ``engine`` (before its loop runs); returns the warnings."""
        self.warnings = []
        for axis in AXES:
            self.restore_setting(model_key(axis), partial(self._apply_model, engine, axis))
            self.restore_setting(gains_key(axis), partial(self._apply_gains, engine, axis))
        self.tracking_restored = self.restore_setting(
            TRACKING_KEY, lambda value: self._apply_tracking(engine, value))
        return list(self.warnings)

    def restore_setting(self, key: str, apply: Callable[[Any], object], version: int = VERSION) -> bool:
        """Read ``key`` and hand its value to ``apply`` (which validates and applies it, raising
        TrackerError, ValueError, TypeError, KeyError or ArithmeticError to refuse it).

        Any part of the service restores its own settings this way (the audio policy, say): a
        refused, unreadable or other-version value is logged and listed in :attr:`warnings`
        (status shows them), and False is returned: keep the default. True when applied; False
        too when nothing is stored."""
        try:
            stored = self.store.get(key)
            if stored is None:
                return False
            if stored.version != version:
                raise ValueError(f"stored with version {stored.version}; this service reads {version}")
            what = apply(stored.value)
        except (TrackerError, ValueError, TypeError, KeyError, ArithmeticError) as exc:
            message = f"{key}: stored value not restored, default kept ({type(exc).__name__}: {exc})"
            log.warning("%s", message)
            self.warnings.append(message)
            return False
        log.info("restored %s: %s", key, what)
        return True

    @staticmethod
    def _apply_model(engine: Any, axis: str, value: dict[str, Any]) -> str:  # noqa: ANN401
        data = value["model"]
        if data.get("axis") != axis:
            raise ValueError(f"the stored model is for {data.get('axis')!r}, not {axis}")
        engine.set_model(axis, model_from_json(data))
        return f"model {data['effects']} (version {value.get('version_id')})"

    @staticmethod
    def _apply_gains(engine: Any, axis: str, value: dict[str, Any]) -> str:  # noqa: ANN401
        current = engine.gains(axis)
        kind = type(current).__name__
        if value["type"] != kind:
            raise ValueError(f"stored gains are {value['type']}, the controller takes {kind}")
        fields = value["fields"]
        names = {f.name for f in dataclasses.fields(current)}
        unknown = sorted(set(fields) - names)
        if unknown:
            raise ValueError(f"unknown gain field(s) {', '.join(unknown)} for {kind}")
        gains = dataclasses.replace(current, **{k: float(v) for k, v in fields.items()})
        engine.set_gains(axis, gains)
        return repr(gains)

    @staticmethod
    def _apply_tracking(engine: Any, value: dict[str, Any]) -> str:  # noqa: ANN401
        enabled = value["enabled"]
        if not isinstance(enabled, bool):
            raise TypeError(f"enabled is {enabled!r}, not true or false")
        engine.set_tracking(enabled)
        return "on" if enabled else "off"

    def clear_warnings(self, *keys: str) -> None:
        """``keys`` were set anew since start-up: their restore warnings no longer apply."""
        self.warnings = [w for w in self.warnings if not w.startswith(tuple(k + ":" for k in keys))]
