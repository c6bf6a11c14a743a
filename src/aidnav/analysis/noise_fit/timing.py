"""Wall time of the stages of a characterisation."""

from __future__ import annotations

import time


class Stages:
    """Wall time of the stages of :func:`characterise_file` into a dict (None: not recorded)."""

    def __init__(self, out: dict | None):
        self.out, self._clock = out, time.perf_counter
        self._t = self._clock()

    def lap(self, name: str) -> None:
        now = self._clock()
        if self.out is not None:
            self.out[name] = self.out.get(name, 0.0) + now - self._t
        self._t = now
