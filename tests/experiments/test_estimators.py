"""Estimator registry: custom estimator types, the loosely coupled filter's configuration."""

from __future__ import annotations

import copy
import math

import numpy as np
import pyarrow.parquet as pq
import pytest
from pydantic import BaseModel, ConfigDict

from aidnav.experiments import estimators as em
from aidnav.experiments.config import ExperimentError, parse_experiment
from aidnav.experiments.runner import run_experiment


class _DummyConfig(BaseModel):
    model_config = ConfigDict(extra="forbid")
    sigma_deg: float = 0.1
    every_s: float = 1.0


@em.register_estimator("test_dummy", config_model=_DummyConfig, states=("att_e", "att_n", "att_u"))
def _dummy(sim, cfg: _DummyConfig, rng):
    """Attitude 'estimates' = truth + N(0, σ²) with a full covariance."""
    t = sim.truth.time
    idx = np.arange(0, len(t), int(round(cfg.every_s / (t[1] - t[0]))))[1:]
    s = math.radians(cfg.sigma_deg)
    err = rng.normal(0.0, s, (len(idx), 3))
    cov = np.broadcast_to(np.eye(3) * s * s, (len(idx), 3, 3)).copy()
    return em.EstimatorOutput(time=t[idx], error=err, cov=cov, states=("att_e", "att_n", "att_u"),
                              info={"n": len(idx)})


def test_registry():
    assert "loose" in em.estimator_types() and "test_dummy" in em.estimator_types()
    with pytest.raises(KeyError, match="registered: .*loose"):
        em.get_estimator("nope")
    assert em.get_estimator("aidnav.experiments.estimators:loose_estimator").name == "loose"
    assert em.state_unit("att_u") == ("deg", 180 / math.pi)
    assert em.state_blocks(("pos_e", "pos_n", "vel_e", "att_u")) == {"pos": [0, 1], "vel": [2], "att": [3]}


def test_custom_estimator_campaign(tmp_path, tiny_doc):
    d = tiny_doc
    d["estimators"] = [{"name": "d1", "type": "test_dummy", "sigma_deg": 0.2},
                       {"name": "d2", "type": "test_dummy", "sigma_deg": 0.4, "every_s": 2.0}]
    d["runs"] = 40
    d["statistics"] = {"metrics": ["std", "rms"]}
    plan = parse_experiment(d, "dummy.yaml")
    res = run_experiment(plan, tmp_path, progress=False)
    assert res.complete
    runs = pq.read_table(tmp_path / "runs.parquet").to_pandas()
    assert len(runs) == 2 * 2 * 40
    # errors are reported in degrees; the same stream → d2 = 2 × d1 draws on the common epochs
    d1 = runs[runs.estimator == "d1"]["rms_all_heading_deg"].to_numpy()
    assert 0.15 < d1.mean() < 0.25
    for c in res.consistency:
        assert c["consistent"], c
    bad = copy.deepcopy(d)
    bad["estimators"][0]["sigma"] = 1
    with pytest.raises(ExperimentError, match=r"estimators\.0\.sigma: unknown key 'sigma' .*sigma_deg"):
        parse_experiment(bad, "dummy.yaml")


def test_loose_q_scale_and_overrides():
    from aidnav.filters.loose import process_noise
    from aidnav.sim.gnss import GnssSpec
    from aidnav.sim.imu import ImuSpec

    imu, gnss = ImuSpec.grade("tactical"), GnssSpec(rate_hz=2)
    base = em.loose_filter_config(em.LooseEstimatorConfig(), imu, gnss, 100.0)
    small = em.loose_filter_config(em.LooseEstimatorConfig(q_scale=0.01), imu, gnss, 100.0)
    np.testing.assert_allclose(process_noise(small, 15), 0.01 * process_noise(base, 15), rtol=1e-12)
    assert base.filter.output_rate_hz == 2.0
    o = em.loose_filter_config(em.LooseEstimatorConfig.model_validate(
        {"config": {"imu": {"arw_deg_sqrt_h": 0.5}, "filter": {"output_rate_hz": 10}}, "r_scale": 4.0}),
        imu, gnss, 100.0)
    assert o.imu.arw_deg_sqrt_h == 0.5 and o.filter.output_rate_hz == 10
    assert o.gnss.pos_std_scale == pytest.approx(2.0)
