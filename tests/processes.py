"""Helpers for tests that start and kill real processes."""

from __future__ import annotations

from pathlib import Path


def process_gone(pid: int) -> bool:
    """Whether ``pid`` has ended (no longer listed, or a zombie waiting for its parent)."""
    try:
        return "State:\tZ" in Path(f"/proc/{pid}/status").read_text()
    except FileNotFoundError:
        return True
