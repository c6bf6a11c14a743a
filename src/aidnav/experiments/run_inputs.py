"""What a Monte Carlo run is made of (:mod:`aidnav.experiments.runner`): per sweep point, cached per
process, the validated context (scenario, sensor specs, estimators), the truth trajectory and the
noise-free GNSS fixes (:class:`GnssTemplate`); per run, its random streams and the sensor draws on them
(:func:`simulate_run`). Units: the simulator's (radians, metres, seconds, ENU velocities; IMU increments
in the body frame RFU)."""

from __future__ import annotations

import hashlib
import importlib
import json
from collections import OrderedDict
from dataclasses import dataclass, replace

import numpy as np

from aidnav.data import GnssData, Trajectory
from aidnav.nav.earth import radii
from aidnav.nav.rotations import wrap_pi
from aidnav.sim.gnss import GnssSpec, simulate_gnss
from aidnav.sim.imu import ImuSpec, corrupt_imu
from aidnav.sim.run import SimulationResult
from aidnav.sim.trajectory import generate_truth

from .config import Experiment, build_scenario
from .estimators import get_estimator

__all__ = ["GnssTemplate", "point_truth", "simulate_run"]


# ----------------------------------------------------------------------------- per-process caches
@dataclass
class _Context:
    key: str
    base_seed: int
    scenario: object
    imu_spec: object
    gnss_spec: object
    estimators: list
    sim_key: str
    gnss_key: str


_CONTEXTS: OrderedDict[str, _Context] = OrderedDict()
TRUTH_KEY: OrderedDict[str, tuple] = OrderedDict()
GNSS_KEY: OrderedDict[tuple, GnssTemplate] = OrderedDict()
_CACHE_SIZE = 3


def cached_point(cache: OrderedDict, key, make):
    if key in cache:
        cache.move_to_end(key)
        return cache[key]
    val = make()
    cache[key] = val
    while len(cache) > _CACHE_SIZE:
        cache.popitem(last=False)
    return val


def point_context(key: str, doc: dict) -> _Context:
    def make():
        for mod in doc.get("imports", []):
            importlib.import_module(mod)
        exp = Experiment.model_validate(doc)
        scn = build_scenario(exp, exp.name)
        ests = []
        for entry in doc["estimators"]:
            et = get_estimator(entry["type"])
            cfg = et.config_model.model_validate({k: v for k, v in entry.items()
                                                  if k not in ("name", "type")})
            ests.append((entry["name"], et, cfg))
        sim_key = hashlib.sha256(json.dumps(doc["scenario"], sort_keys=True).encode()).hexdigest()
        gnss_key = json.dumps(doc["sensors"]["gnss"], sort_keys=True)
        return _Context(key, int(doc["base_seed"]), scn, ImuSpec.from_config(exp.sensors.imu),
                        GnssSpec.from_config(exp.sensors.gnss), ests, sim_key, gnss_key)

    return cached_point(_CONTEXTS, key, make)


def truth_of_point(ctx: _Context):
    return cached_point(TRUTH_KEY, ctx.sim_key, lambda: generate_truth(ctx.scenario))


@dataclass
class GnssTemplate:
    """Noise-free GNSS fixes of one trajectory and receiver (generated once per sweep point), to which
    each run adds its noise exactly as :func:`aidnav.sim.gnss.simulate_gnss` does (same draws: position
    then velocity unit normals for every tag, before outages are removed).

    base : fixes simulated with zero σ (antenna lat/lon [rad], height [m], ENU velocity [m/s]);
    keep : (M_all,) which of all tags survive outages and latency; spec : the receiver.
    """

    base: object
    keep: np.ndarray
    spec: object

    @classmethod
    def build(cls, truth, spec) -> GnssTemplate:
        spec0 = replace(spec, sigma_pos_enu=np.zeros(3), sigma_vel_enu=np.zeros(3))
        t = np.asarray(truth.time, dtype=float)
        n_tags = int(np.floor((t[-1] - t[0]) * spec.rate_hz + 1e-9))
        tags = t[0] + np.arange(1, n_tags + 1) / spec.rate_hz
        tags = tags[tags <= t[-1] + 1e-9]
        base = simulate_gnss(_around(truth, tags, spec.latency_s), spec0, np.random.default_rng(0))
        return cls(base=base, keep=np.isin(tags, base.time), spec=spec)

    def draw(self, rng: np.random.Generator):
        """Noisy fixes (:class:`aidnav.data.GnssData`) with the noise drawn from ``rng``."""
        m_all = len(self.keep)
        zp = rng.standard_normal((m_all, 3))[self.keep]
        zv = rng.standard_normal((m_all, 3))[self.keep]
        b, sp = self.base, self.spec.sigma_pos_enu
        m = len(b.time)
        ne = zp * sp
        rm, rn = radii(b.lat)
        lat = b.lat + ne[:, 1] / (rm + b.height)
        lon = b.lon + ne[:, 0] / ((rn + b.height) * np.cos(b.lat))
        lon = wrap_pi(lon)
        h = b.height + ne[:, 2]
        vel = std_vel = None
        if self.spec.velocity:
            vel = b.vel + zv * self.spec.sigma_vel_enu
            std_vel = np.tile(self.spec.sigma_vel_enu, (m, 1))
        return GnssData(b.time.copy(), lat, lon, h, vel, np.tile(sp, (m, 1)), std_vel, None, list(b.events))


def _around(truth, tags: np.ndarray, latency_s: float):
    """The truth's samples that :func:`aidnav.sim.gnss.simulate_gnss` reads for fixes tagged ``tags`` (the
    first and last, and k − 1 … k + 2 around the interval k of each time a fix describes: the Hermite
    interpolation reads k, k + 1, the attitude rate the midpoints of k − 1 … k + 2): the same fixes, bit for
    bit (every quantity there is computed sample by sample or from adjacent samples; test
    ``test_gnss_template_matches_simulate_gnss``), for ~2 % of a 100-Hz truth's samples at 1 Hz (the
    template of a 30-min flight: ≈ 0.1 s less before a campaign's workers start). ``truth`` itself where
    that would keep most of it."""
    t = np.asarray(truth.time, dtype=float)
    n = len(t)
    at = np.concatenate([tags, np.maximum(np.minimum(tags - latency_s, t[-1]), t[0])])
    k = np.clip(np.searchsorted(t, at, side="right") - 1, 0, max(n - 2, 0))
    idx = np.unique(np.concatenate([[0, n - 1], (k[:, None] + np.arange(-1, 3)).ravel()]))
    idx = idx[(idx >= 0) & (idx < n)]
    if len(idx) * 2 > n:
        return truth
    return Trajectory(t[idx], np.asarray(truth.lat)[idx], np.asarray(truth.lon)[idx],
                      np.asarray(truth.height)[idx], np.asarray(truth.vel)[idx], np.asarray(truth.rph)[idx])


def gnss_template(ctx: _Context, truth) -> GnssTemplate:
    return cached_point(GNSS_KEY, (ctx.sim_key, ctx.gnss_key),
                        lambda: GnssTemplate.build(truth, ctx.gnss_spec))


def point_truth(point):
    """Truth trajectory of a sweep point (cached per process)."""
    return truth_of_point(point_context(point.key, point.doc))[0]


# ----------------------------------------------------------------------------------- one run
def run_streams(base_seed: int, run: int):
    ss = np.random.SeedSequence(base_seed, spawn_key=(run,))
    return ss.spawn(3)


def simulate_run(ctx: _Context, run: int, out=None):
    """The :class:`aidnav.sim.run.SimulationResult` of run ``run`` of a point (and the estimator stream);
    ``out``: where to write the corrupted increments (:func:`aidnav.sim.imu.corrupt_imu`)."""
    truth, imu_true, segments = truth_of_point(ctx)
    tmpl = gnss_template(ctx, truth)
    s_imu, s_gnss, s_est = run_streams(ctx.base_seed, run)
    imu, realised = corrupt_imu(imu_true, ctx.imu_spec, np.random.default_rng(s_imu), out=out)
    gnss = tmpl.draw(np.random.default_rng(s_gnss))
    sim = SimulationResult(ctx.scenario, ctx.base_seed, truth, imu_true, imu, gnss, segments, realised)
    return sim, s_est
