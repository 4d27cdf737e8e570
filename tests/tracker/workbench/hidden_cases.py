"""Shared, cached hidden-effect measurements for the diagnosis tests (generated once per session)."""

from __future__ import annotations

from functools import cache

from tracker.plant.model import AxisModel
from tracker.workbench.experiments.experiments import generate_measurement, random_hidden_model
from tracker.workbench.measurements.data import Measurement

DURATION_S = 24.0


@cache
def hidden_case(effects: tuple[str, ...], seed: int) -> tuple[AxisModel, Measurement]:
    """The true rig (pan preset + ``effects`` at random physical parameters) and its closed-loop log."""
    true = random_hidden_model("pan", effects, seed) if effects else AxisModel.for_axis("pan")
    return true, generate_measurement(true, DURATION_S, seed=seed)
