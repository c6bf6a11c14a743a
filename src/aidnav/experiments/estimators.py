"""Estimator registry of the experiment runner: a name → callable(sim_result, estimator_cfg, rng).

An *estimator type* turns one simulated run (:class:`aidnav.sim.run.SimulationResult`: truth, corrupted
IMU, GNSS fixes, the scenario with its sensor settings) into per-epoch errors and their covariance
(:class:`EstimatorOutput`). Experiments name a type in each entry of their ``estimators`` list and give
its configuration there; the configuration is validated by the type's pydantic model before any
computation (unknown keys and bad values are reported with their key path).

Registering a new type (e.g. in a seed's module, listed under ``imports:`` in the experiment so that
worker processes import it too)::

    from aidnav.experiments.estimators import EstimatorOutput, register_estimator

    class MyConfig(BaseModel):
        model_config = ConfigDict(extra="forbid")
        gain: float = 1.0

    @register_estimator("my_filter", config_model=MyConfig, states=("att_e", "att_n", "att_u"))
    def my_filter(sim, cfg: MyConfig, rng) -> EstimatorOutput:
        ...

A type may also be named ``"package.module:function"`` in an experiment: the module is imported (which
registers it) and the function is looked up in the registry.

Conventions of :class:`EstimatorOutput` (``docs/conventions.md``): errors are **estimate − truth** in SI units
(position in ENU metres, velocity ENU m/s, attitude as the misalignment φ in n [rad] with
C_b^n(est) = (I − [φ×]) C_b^n(true)), times in the simulation's time scale (seconds since its start).
State names are ``<block>_<component>`` (``pos_e``, ``vel_u``, ``att_n``, ...); states sharing a block
prefix form one NEES block. Boundary units of a block (used in the result tables) come from
:data:`BLOCK_UNITS`: ``pos`` m, ``vel`` m/s, ``att`` deg; other blocks keep SI units.
"""

from __future__ import annotations

import importlib
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from aidnav.analysis.errors import ins_error_state, truth_index
from aidnav.filters.loose import run_loose, run_loose_batch
from aidnav.filters.tuning import loose_config_from_specs, perturbed_initial_state
from aidnav.nav.earth import lla_difference_enu, radii
from aidnav.sim.gnss import GnssSpec
from aidnav.sim.imu import ImuSpec
from aidnav.units import DEG

__all__ = [
    "EstimatorOutput", "EstimatorType", "register_estimator", "get_estimator", "estimator_types",
    "BLOCK_UNITS", "state_unit", "state_blocks", "LOOSE_STATES", "LooseEstimatorConfig", "loose_estimator",
    "loose_errors",
]

#: Boundary unit (column-name suffix) and factor from SI, per state block prefix.
BLOCK_UNITS: dict[str, tuple[str, float]] = {
    "pos": ("m", 1.0),
    "vel": ("m_s", 1.0),
    "att": ("deg", 1.0 / DEG),
}


def state_unit(state: str) -> tuple[str, float]:
    """(unit suffix, factor SI → boundary unit) of a state name ``<block>_<component>``."""
    return BLOCK_UNITS.get(state.split("_", 1)[0], ("si", 1.0))


def state_blocks(states: tuple[str, ...] | list[str]) -> dict[str, list[int]]:
    """NEES blocks: indices of the states sharing each block prefix, in order of first appearance."""
    out: dict[str, list[int]] = {}
    for i, s in enumerate(states):
        out.setdefault(s.split("_", 1)[0], []).append(i)
    return out


@dataclass
class EstimatorOutput:
    """Per-epoch errors of one estimator on one run.

    time : (N,) epochs [s] (the simulation's time scale: seconds since its start), strictly increasing.
    error : (N, n) estimate − truth in SI units (see the module docstring), states named by ``states``.
    cov : the estimator's covariance of those errors, SI: (N, n, n) full, or (N, n) variances (diagonal;
        NEES then ignores correlations between the states of a block).
    states : n state names ``<block>_<component>``.
    info : free-form counters (JSON-able) kept in the run file.
    """

    time: np.ndarray
    error: np.ndarray
    cov: np.ndarray
    states: tuple[str, ...]
    info: dict = field(default_factory=dict)

    def check(self, name: str = "estimator") -> None:
        """Raise ValueError when the shapes do not agree."""
        n_ep, n = len(self.time), len(self.states)
        if self.error.shape != (n_ep, n):
            raise ValueError(f"{name}: error has shape {self.error.shape}, expected ({n_ep}, {n})")
        if self.cov.shape not in ((n_ep, n), (n_ep, n, n)):
            raise ValueError(f"{name}: cov has shape {self.cov.shape}, expected ({n_ep}, {n}) or "
                             f"({n_ep}, {n}, {n})")
        if n_ep > 1 and np.any(np.diff(self.time) <= 0):
            raise ValueError(f"{name}: epochs must be strictly increasing")

    def variances(self) -> np.ndarray:
        """(N, n) variances (the diagonal of ``cov``)."""
        return self.cov if self.cov.ndim == 2 else np.einsum("kii->ki", self.cov)

    def block_cov(self, idx: list[int]) -> np.ndarray:
        """(N, k, k) covariance of the states ``idx`` (diagonal matrices for a diagonal ``cov``)."""
        if self.cov.ndim == 3:
            return self.cov[:, idx][:, :, idx]
        k = len(idx)
        out = np.zeros((len(self.time), k, k))
        out[:, np.arange(k), np.arange(k)] = self.cov[:, idx]
        return out


@dataclass(frozen=True)
class EstimatorType:
    """A registered estimator: ``fn(sim_result, cfg, rng) -> EstimatorOutput``.

    config_model : pydantic model of the configuration keys of an experiment's estimator entry.
    states : names of the error states it returns (for validating the statistics of an experiment).
    check : optional ``check(cfg, scenario)`` run for every sweep point before any computation; raises
        ValueError (message) or pydantic ValidationError (locations relative to the entry).
    batch : optional ``batch(sim_results, cfg, rngs) -> list[EstimatorOutput] | None``: the same
        estimator on runs of one sweep point together, each output identical to ``fn(sim, cfg, rng)``;
        None when these runs cannot be batched (the runner then calls ``fn`` run by run).
    """

    name: str
    fn: Callable[[Any, BaseModel, np.random.Generator], EstimatorOutput]
    config_model: type[BaseModel]
    states: tuple[str, ...]
    check: Callable[[BaseModel, Any], None] | None = None
    batch: Callable[[list, BaseModel, list], list | None] | None = None


_REGISTRY: dict[str, EstimatorType] = {}


def register_estimator(name: str, config_model: type[BaseModel], states: tuple[str, ...] | list[str],
                       check: Callable[[BaseModel, Any], None] | None = None, batch=None):
    """Decorator registering ``fn(sim_result, cfg, rng) -> EstimatorOutput`` under ``name`` (``batch``:
    see :class:`EstimatorType`)."""

    def deco(fn):
        _REGISTRY[name] = EstimatorType(name, fn, config_model, tuple(states), check, batch)
        return fn

    return deco


def get_estimator(name: str) -> EstimatorType:
    """The registered type ``name``; ``"package.module:function"`` imports the module first.

    Raises KeyError with the registered names when there is none.
    """
    if name in _REGISTRY:
        return _REGISTRY[name]
    if ":" in name:
        mod, _, attr = name.partition(":")
        importlib.import_module(mod)  # registers
        if name in _REGISTRY:
            return _REGISTRY[name]
        if attr in _REGISTRY:
            return _REGISTRY[attr]
        fn = getattr(importlib.import_module(mod), attr, None)
        for et in _REGISTRY.values():
            if et.fn is fn:
                return et
    raise KeyError(f"unknown estimator type {name!r} (registered: {', '.join(estimator_types())})")


def estimator_types() -> list[str]:
    """Names of the registered estimator types."""
    return sorted(_REGISTRY)


# ------------------------------------------------------------------------ loosely coupled filter
LOOSE_STATES = ("pos_e", "pos_n", "pos_u", "vel_e", "vel_n", "vel_u", "att_e", "att_n", "att_u")

Vec3 = tuple[float, float, float]


class LooseEstimatorConfig(BaseModel):
    """Configuration of the ``loose`` estimator (:func:`aidnav.filters.loose.run_loose`).

    The filter is tuned to the simulated sensors (:func:`aidnav.filters.tuning.loose_config_from_specs`:
    truth model = filter model where the 15/21-state model can represent it), started from an initial
    state drawn around the truth with the ``init_*`` 1σ's (which are also its initial covariance), then:

    config : LooseConfig section overrides merged into the tuned configuration, e.g.
        ``{imu: {arw_deg_sqrt_h: 0.01}, gnss: {gate_probability: 0.999}}`` (keys of
        :class:`aidnav.filters.config.LooseConfig`).
    q_scale : multiplies the whole continuous process-noise PSD after the overrides (ARW², VRW², bias
        driving noise); 0.01 = "Q 100× too small". r_scale : multiplies the GNSS measurement variances.
    states : 15 or 21 (with scale factors; the filter's sensor model is the one before issue 35, one
    Gauss-Markov bias state, so that ``states`` and ``q_scale`` keep their meaning). prop_dt_s : largest
    covariance propagation step [s].
    output_rate_hz : rate of the error epochs [Hz]; None = the GNSS rate. The epochs are every
        ``round(imu_rate / output_rate)``-th IMU sample from the first one.
    smooth : evaluate the RTS-smoothed solution instead of the forward filter.
    init_position_sigma_m (ENU) [m], init_velocity_sigma_m_s (ENU) [m/s], init_attitude_sigma_deg
        (roll, pitch, heading as a misalignment E, N, U) [deg].
    """

    model_config = ConfigDict(extra="forbid")

    states: Literal[15, 21] = 15
    q_scale: float = Field(1.0, gt=0)
    r_scale: float = Field(1.0, gt=0)
    prop_dt_s: float = Field(1.0, gt=0)
    output_rate_hz: float | None = Field(None, gt=0)
    smooth: bool = False
    init_position_sigma_m: tuple[float, float, float] = Field((1.0, 1.0, 1.0))
    init_velocity_sigma_m_s: tuple[float, float, float] = Field((0.1, 0.1, 0.1))
    init_attitude_sigma_deg: tuple[float, float, float] = Field((0.1, 0.1, 1.0))
    config: dict[str, dict[str, Any]] = Field(default_factory=dict)


def _specs(scenario):
    return ImuSpec.from_config(scenario.sensors.imu), GnssSpec.from_config(scenario.sensors.gnss)


def loose_filter_config(cfg: LooseEstimatorConfig, imu_spec, gnss_spec, imu_rate_hz: float, init=None):
    """The :class:`aidnav.filters.config.LooseConfig` of an estimator entry.

    init : (lla_deg_m, vel ENU [m/s], rph_deg) of the filter's initial state, or None (validation only).
    Raises pydantic ValidationError (locations in LooseConfig) for bad ``config`` overrides.
    """
    over = {k: dict(v) for k, v in cfg.config.items()}
    rate = cfg.output_rate_hz if cfg.output_rate_hz is not None else gnss_spec.rate_hz
    filt = {"output_rate_hz": min(float(rate), float(imu_rate_hz)), **over.pop("filter", {})}
    kw = {}
    if init is not None:
        kw = dict(init_lla_deg_m=init[0], init_vel=init[1], init_rph_deg=init[2])
    lcfg = loose_config_from_specs(imu_spec, gnss_spec, position_sigma_m=cfg.init_position_sigma_m,
                                   velocity_sigma_m_s=cfg.init_velocity_sigma_m_s,
                                   attitude_sigma_deg=cfg.init_attitude_sigma_deg, states=cfg.states,
                                   prop_dt_s=cfg.prop_dt_s, filter=filt, sensor_model=False, **kw, **over)
    if cfg.q_scale != 1.0:
        s = math.sqrt(cfg.q_scale)
        im = lcfg.imu
        gi = im.gyro_bias_instability_deg_h
        gi = im.gyro_bias_sigma_deg_h if gi is None else gi
        ai = im.accel_bias_instability_ug
        ai = im.accel_bias_sigma_ug if ai is None else ai
        upd = dict(arw_deg_sqrt_h=im.arw_deg_sqrt_h * s, vrw_m_s_sqrt_h=im.vrw_m_s_sqrt_h * s,
                   gyro_bias_instability_deg_h=gi * s, accel_bias_instability_ug=ai * s,
                   gyro_bias_rw_deg_h_sqrt_h=im.gyro_bias_rw_deg_h_sqrt_h * s,
                   accel_bias_rw_ug_sqrt_h=im.accel_bias_rw_ug_sqrt_h * s)
        lcfg = lcfg.model_copy(update={"imu": im.model_copy(update=upd)})
    if cfg.r_scale != 1.0:
        s = math.sqrt(cfg.r_scale)
        g = lcfg.gnss
        lcfg = lcfg.model_copy(update={"gnss": g.model_copy(update=dict(
            pos_std_scale=g.pos_std_scale * s, vel_std_scale=g.vel_std_scale * s))})
    return lcfg


def loose_errors(res, truth) -> EstimatorOutput:
    """Errors of a :class:`aidnav.filters.loose.LooseResult` against the truth at its output epochs.

    The output epochs must be truth epochs (simulated data: both at the IMU times). Position errors are
    ENU metres at the truth position (:func:`aidnav.nav.earth.lla_difference_enu`), attitude errors the
    misalignment φ of :func:`aidnav.nav.rotations.attitude_error_batch`; the covariance is the filter's
    diagonal (δL, δλ converted to metres with the radii at the truth position).
    """
    # analysis.errors imports pandas and scipy: loaded when a campaign scores, not with the registry

    t = np.asarray(res.time, dtype=float)
    idx = truth_index(truth.time, t)
    e = ins_error_state(res, truth)  # φ, δv, δL, δλ, δh at the same truth samples
    st = res.state
    lat, lon, h = truth.lat[idx], truth.lon[idx], truth.height[idx]
    de, dn, du = lla_difference_enu(st[:, 0], st[:, 1], st[:, 2], lat, lon, h)
    err = np.column_stack([de, dn, du, e[:, 3:6], e[:, 0:3]])
    pd = np.maximum(res.pdiag, 0.0)
    rm, rn = radii(lat)
    var = np.column_stack([pd[:, 7] * ((rn + h) * np.cos(lat)) ** 2, pd[:, 6] * (rm + h) ** 2, pd[:, 8],
                           pd[:, 3:6], pd[:, 0:3]])
    info = {k: v for k, v in res.counts.items() if isinstance(v, (int, float))}
    return EstimatorOutput(time=t, error=err, cov=var, states=LOOSE_STATES, info=info)


def _loose_check(cfg: LooseEstimatorConfig, scenario) -> None:
    imu_spec, gnss_spec = _specs(scenario)
    loose_filter_config(cfg, imu_spec, gnss_spec, scenario.imu_rate_hz)


def _loose_run_config(sim, cfg: LooseEstimatorConfig, rng: np.random.Generator):
    """The filter configuration of one run: tuned to the sensors, started from an initial state drawn from
    ``rng`` (:func:`aidnav.filters.tuning.perturbed_initial_state`)."""
    imu_spec, gnss_spec = _specs(sim.scenario)
    init = perturbed_initial_state(sim.truth, rng, cfg.init_position_sigma_m, cfg.init_velocity_sigma_m_s,
                                   cfg.init_attitude_sigma_deg)
    return loose_filter_config(cfg, imu_spec, gnss_spec, sim.scenario.imu_rate_hz, init=init)


def loose_estimator_batch(sims, cfg: LooseEstimatorConfig, rngs) -> list[EstimatorOutput] | None:
    """:func:`loose_estimator` on runs of one sweep point together
    (:func:`aidnav.filters.loose.run_loose_batch`); None with the smoother or when they cannot be batched."""
    if cfg.smooth:
        return None
    cfgs = [_loose_run_config(sim, cfg, rng) for sim, rng in zip(sims, rngs, strict=True)]
    res = run_loose_batch([s.imu for s in sims], [s.gnss for s in sims], cfgs)
    return None if res is None else [loose_errors(r, s.truth) for r, s in zip(res, sims, strict=True)]


@register_estimator("loose", config_model=LooseEstimatorConfig, states=LOOSE_STATES, check=_loose_check,
                    batch=loose_estimator_batch)
def loose_estimator(sim, cfg: LooseEstimatorConfig, rng: np.random.Generator) -> EstimatorOutput:
    """Loosely coupled GNSS/INS on one simulated run (see :class:`LooseEstimatorConfig`).

    ``rng`` draws the initial-state error (:func:`aidnav.filters.tuning.perturbed_initial_state`).
    """
    res = run_loose(sim.imu, sim.gnss, _loose_run_config(sim, cfg, rng), smooth=cfg.smooth)
    return loose_errors(res, sim.truth)
