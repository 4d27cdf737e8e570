"""The engine's one exception tree.

TrackerError            root of everything the engine raises on purpose
├── ConfigError         bad configuration: unknown effect or parameter, out-of-bounds value,
│   │                   unstable gains (also a ValueError)
│   ├── ModelRefused    a model offered to a controller does not predict the axis's recent
│   │                   motion (``figures`` holds the check's numbers)
│   └── OutOfRange      a named setting outside its bounds (``name``, ``low``, ``high``, ``unit``)
├── DataError           bad measurement or audio data: missing column, NaN, uneven sampling
│                       (also a ValueError); the message names the line or column
├── DriverFault         a motor or audio driver failed or refused (device missing, fault latched)
└── JobCancelled        a long job (fit, friction-ID) was cancelled by its caller

The service (``app/``) maps these to HTTP statuses in one place; the command line prints
``error: <message>`` and exits non-zero.
"""

from __future__ import annotations

from collections.abc import Mapping


class TrackerError(Exception):
    """Root of every error the engine raises on purpose."""


class ConfigError(TrackerError, ValueError):
    """A configuration value is unknown, out of bounds or unsafe."""


class ModelRefused(ConfigError):
    """A model offered to a controller does not predict the axis's recent motion.

    ``figures`` holds the check's numbers in SI units (``tracker.model_check.ModelCheck.to_dict``).
    """

    def __init__(self, message: str, figures: Mapping[str, object]) -> None:
        super().__init__(message)
        self.figures = dict(figures)


class OutOfRange(ConfigError):
    """A named setting outside its bounds: ``name``, ``value``, ``low``, ``high``, ``unit``."""

    def __init__(self, message: str, name: str, value: object, low: float, high: float,
                 unit: str) -> None:
        super().__init__(message)
        self.name, self.value, self.low, self.high, self.unit = name, value, low, high, unit


class DataError(TrackerError, ValueError):
    """Measurement or audio data cannot be used; the message says where."""


class DriverFault(TrackerError):
    """A hardware or simulated driver reported a fault or is unavailable."""


class JobCancelled(TrackerError):
    """A long-running job was cancelled by its caller."""
