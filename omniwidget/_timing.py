"""Seconds per stage, as ``Result.timings`` reports them."""

from __future__ import annotations

import time

__all__ = ["Laps"]


class Laps:
    """``laps(name)`` adds the seconds since the last lap to ``timings[name]`` (nothing when ``timings`` is None)."""

    def __init__(self, timings: dict[str, float] | None) -> None:
        self.timings, self.clock = timings, time.perf_counter()

    def __call__(self, name: str) -> None:
        now = time.perf_counter()
        if self.timings is not None:
            self.timings[name] = self.timings.get(name, 0.0) + now - self.clock
        self.clock = now
