"""The outside generator redraws a log whose plant diverged (seed 19 stopped the whole matrix)."""

from __future__ import annotations

from typing import Any

import pytest

import bench.outside_gen.generate as generate


def test_a_diverging_draw_is_redrawn_with_the_next_seed(monkeypatch: pytest.MonkeyPatch) -> None:
    real = generate.build_once
    seeds: list[int] = []

    def first_diverges(name: str, seed: int, effect: str | None, duration_s: float = 20.0) -> Any:
        seeds.append(seed)
        if len(seeds) == 1:
            raise FloatingPointError("plant diverged at tick 3")
        return real(name, seed, effect, duration_s)

    monkeypatch.setattr(generate, "build_once", first_diverges)
    sc, run = generate.build("clean-x", 5, None, duration_s=1.0)
    assert seeds == [5, 5 + 7919]
    assert run.t_s.size > 0 and sc is not None


def test_a_plant_that_diverges_in_every_draw_says_so(monkeypatch: pytest.MonkeyPatch) -> None:
    def always(name: str, seed: int, effect: str | None, duration_s: float = 20.0) -> Any:
        raise FloatingPointError("plant diverged at tick 3")

    monkeypatch.setattr(generate, "build_once", always)
    with pytest.raises(FloatingPointError, match=r"clean-x \(seed 5\).*all 3 draws"):
        generate.build("clean-x", 5, None, duration_s=1.0, tries=3)
