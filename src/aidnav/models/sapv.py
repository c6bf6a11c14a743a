"""Tracking-status codes of a satcom antenna platform's angle outputs (seed 000), shared by the SAPV
simulator (:mod:`aidnav.sim.sapv`) and the federated filter's input check
(:mod:`aidnav.filters.federated`)."""

from __future__ import annotations

__all__ = ["OK", "BLOCKED", "LOW_ELEVATION", "BODY_RATE", "REACQUIRING", "REASONS"]

OK, BLOCKED, LOW_ELEVATION, BODY_RATE, REACQUIRING = 0, 1, 2, 3, 4
REASONS = {OK: "tracking", BLOCKED: "blocked", LOW_ELEVATION: "elevation below mask",
           BODY_RATE: "body rate above tracking limit", REACQUIRING: "re-acquiring"}
