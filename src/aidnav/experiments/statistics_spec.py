"""What an experiment reports per run: the ``statistics`` section of an experiment file (windows,
metrics, convergence, NEES consistency), the quantities an estimator supports and the columns of
``runs.parquet`` they produce. Shared by :mod:`.config` (validation) and :mod:`.store` (writing)."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from . import estimators as est_mod

__all__ = ["Metric", "WindowSpec", "ConvergenceSpec", "ConsistencySpec", "StatisticsSpec",
           "DERIVED_QUANTITIES", "quantity_column", "available_quantities", "statistic_columns"]

_NAME = r"^[A-Za-z0-9][A-Za-z0-9_.+-]*$"
Positive = Annotated[float, Field(gt=0)]
NonNegative = Annotated[float, Field(ge=0)]


class StrictModel(BaseModel):
    model_config = ConfigDict(extra="forbid", validate_default=True)


Metric = Literal["std", "rms", "mean", "max"]


class WindowSpec(StrictModel):
    """A time window of the statistics: a named segment, or ``start_s``/``end_s`` [s since the start]
    (either may be missing), or the last ``last_s`` seconds; nothing = the whole run. ``metrics``
    replaces the statistics' default metrics for this window."""

    segment: str | None = None
    start_s: NonNegative | None = None
    end_s: NonNegative | None = None
    last_s: Positive | None = None
    metrics: list[Metric] | None = None

    @model_validator(mode="after")
    def _one_kind(self):
        kinds = [self.segment is not None, self.start_s is not None or self.end_s is not None,
                 self.last_s is not None]
        if sum(kinds) > 1:
            raise ValueError("give one of segment, start_s/end_s or last_s")
        if self.start_s is not None and self.end_s is not None and self.end_s <= self.start_s:
            raise ValueError(f"end_s = {self.end_s} s must be after start_s = {self.start_s} s")
        return self


class ConvergenceSpec(StrictModel):
    """Time [s since the start] of the first epoch after which |error| (``of: error``) or the filter σ
    (``of: sigma``) of ``quantity`` stays <= ``below`` (in the quantity's unit: m, m/s, deg) until the
    end (``hold_s`` None) or for at least ``hold_s`` seconds. NaN when it never does."""

    quantity: str
    below: Positive
    of: Literal["error", "sigma"] = "error"
    hold_s: Positive | None = None


class ConsistencySpec(StrictModel):
    """NEES check per estimator and block (:func:`aidnav.analysis.consistency.consistency_report`).

    prob : probability of the χ² band; alpha : level of the verdict's tests. epoch_spacing_s : the
    verdict uses epochs at least this far apart [s] (errors of a filter are correlated in time, the
    tests assume independent epochs); the plotted NEES uses every epoch.
    """

    prob: float = Field(0.95, gt=0, lt=1)
    alpha: float = Field(1e-3, gt=0, lt=0.5)
    epoch_spacing_s: Positive = 30.0


class StatisticsSpec(StrictModel):
    """What is reported per run (see the module docstring). ``quantities`` None = every state of each
    estimator plus the derived ones it supports."""

    quantities: list[str] | None = None
    metrics: list[Metric] = Field(default_factory=lambda: ["std", "rms"], min_length=1)
    windows: dict[Annotated[str, Field(pattern=_NAME)], WindowSpec] = Field(
        default_factory=lambda: {"all": WindowSpec()})
    convergence: dict[Annotated[str, Field(pattern=_NAME)], ConvergenceSpec] = Field(default_factory=dict)
    consistency: ConsistencySpec = Field(default_factory=ConsistencySpec)


# ------------------------------------------------------------------------------------- quantities
#: Derived quantities: name → (states needed, kind). ``heading`` is an alias of ``att_u``.
DERIVED_QUANTITIES: dict[str, tuple[tuple[str, ...], str]] = {
    "pos_h": (("pos_e", "pos_n"), "norm"),
    "pos_3d": (("pos_e", "pos_n", "pos_u"), "norm"),
    "vel_h": (("vel_e", "vel_n"), "norm"),
    "heading": (("att_u",), "alias"),
}


def quantity_column(q: str) -> str:
    """Column stem of a quantity with its unit: ``pos_h`` → ``pos_h_m``, ``heading`` → ``heading_deg``."""
    if q == "heading":
        return "heading_deg"
    unit, _ = est_mod.state_unit(q)
    return f"{q}_{unit}"


def available_quantities(states: tuple[str, ...]) -> list[str]:
    """Quantities an estimator with ``states`` supports: its states, then the derived ones."""
    return list(states) + [d for d, (need, _) in DERIVED_QUANTITIES.items() if all(s in states for s in need)]


def spec_quantities(stats: StatisticsSpec, states) -> list[str]:
    avail = available_quantities(tuple(states))
    if stats.quantities is None:
        return avail
    return [q for q in stats.quantities if q in avail]


def window_metrics(stats: StatisticsSpec):
    for wname, w in stats.windows.items():
        for m in (w.metrics or stats.metrics):
            yield wname, w, m


def statistic_columns(stats: StatisticsSpec, estimators: list[tuple[str, tuple[str, ...]]]) -> list[str]:
    """Statistics columns of runs.parquet, in order, for estimators given as (name, states):
    ``<metric>_<window>_<quantity>_<unit>``, ``converge_<name>_s``, ``nees_<block>_mean``."""
    cols: list[str] = []

    def add(c):
        if c not in cols:
            cols.append(c)

    qs_all: list[str] = []
    for _, states in estimators:
        for q in spec_quantities(stats, states):
            if q not in qs_all:
                qs_all.append(q)
    if stats.quantities is not None:
        qs_all = [q for q in stats.quantities if q in qs_all]
    for wname, _, m in window_metrics(stats):
        for q in qs_all:
            add(f"{m}_{wname}_{quantity_column(q)}")
    for cname in stats.convergence:
        add(f"converge_{cname}_s")
    for _, states in estimators:
        for b in est_mod.state_blocks(states):
            add(f"nees_{b}_mean")
    return cols
