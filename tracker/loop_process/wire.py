"""What goes over the pipe between the service and the control loop's process: calls, replies,
and errors carried back as the same exception types (a ConfigError stays a ConfigError, so the
service maps it to the same HTTP status).

Engine values cross by pickle; :class:`~tracker.plant.model.AxisModel` holds a read-only mapping
that pickle cannot take, so it is registered here to cross as its fields.
"""

from __future__ import annotations

import copyreg
import pickle
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

from tracker.errors import TrackerError
from tracker.plant.model import AxisModel


def _axis_model(gain_nm_per_v: float, effects: tuple[str, ...], params: dict[str, float]) -> AxisModel:
    return AxisModel(gain_nm_per_v, tuple(effects), MappingProxyType(dict(params)))


def _reduce_axis_model(m: AxisModel) -> tuple[Any, tuple[float, tuple[str, ...], dict[str, float]]]:
    return _axis_model, (m.gain_nm_per_v, tuple(m.effects), dict(m.params))


copyreg.pickle(AxisModel, _reduce_axis_model)


@dataclass(frozen=True, slots=True)
class Call:
    """Run ``method`` of the loop's command table with these arguments."""

    call_id: int
    method: str
    args: tuple[Any, ...] = ()
    kwargs: Mapping[str, Any] = field(default_factory=dict)


@dataclass(frozen=True, slots=True)
class CarriedError:
    """An exception raised in the loop's process, to raise again in the service."""

    kind: type[BaseException]
    args: tuple[Any, ...]
    attrs: Mapping[str, Any]

    @classmethod
    def of(cls, exc: BaseException) -> CarriedError:
        """``exc`` as it can cross (its attributes only if they pickle; else a TrackerError with its text)."""
        attrs = dict(getattr(exc, "__dict__", {}))
        carried = cls(type(exc), tuple(exc.args), attrs)
        try:
            pickle.dumps(carried)
        except Exception:
            return cls(TrackerError, (f"{type(exc).__name__}: {exc}",), {})
        return carried

    def rebuild(self) -> BaseException:
        """The exception again: its type, message and attributes (``__init__`` is not called:
        some take more than the message, e.g. ModelRefused's figures)."""
        exc = self.kind.__new__(self.kind)
        exc.args = self.args
        for name, value in self.attrs.items():
            setattr(exc, name, value)
        return exc


@dataclass(frozen=True, slots=True)
class Reply:
    """The answer to call ``call_id``: its value, or the error it raised."""

    call_id: int
    value: Any = None
    error: CarriedError | None = None


@dataclass(frozen=True, slots=True)
class Ready:
    """The loop's process built its engine: what the service needs to know before any call."""

    config: Any  # the engine's EngineConfig
    sample_period_s: float
    chunk_period_s: float
    driver: Mapping[str, Any]  # what GET /status shows about the driver
