"""The engine's one exception tree.

TrackerError            root of everything the engine raises on purpose
├── ConfigError         bad configuration: unknown effect or parameter, out-of-bounds value,
│                       unstable gains (also a ValueError)
├── DataError           bad measurement or audio data: missing column, NaN, uneven sampling
│                       (also a ValueError); the message names the line or column
├── DriverFault         a motor or audio driver failed or refused (device missing, fault latched)
└── JobCancelled        a long job (fit, friction-ID) was cancelled by its caller

The service (``app/``) maps these to HTTP statuses in one place; the command line prints
``error: <message>`` and exits non-zero.
"""

from __future__ import annotations


class TrackerError(Exception):
    """Root of every error the engine raises on purpose."""


class ConfigError(TrackerError, ValueError):
    """A configuration value is unknown, out of bounds or unsafe."""


class DataError(TrackerError, ValueError):
    """Measurement or audio data cannot be used; the message says where."""


class DriverFault(TrackerError):
    """A hardware or simulated driver reported a fault or is unavailable."""


class JobCancelled(TrackerError):
    """A long-running job was cancelled by its caller."""
