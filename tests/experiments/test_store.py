"""Statistics of the results store and run files."""

from __future__ import annotations

import numpy as np
import pytest

from aidnav.experiments import store
from aidnav.experiments.config import StatisticsSpec


def test_convergence_until_end_and_hold():
    t = np.arange(10.0)
    v = np.array([[5, 5, 0.5, 3, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5],
                  [5, 5, 5, 5, 5, 5, 5, 5, 5, 0.5],
                  [5, 5, 5, 5, 5, 5, 5, 5, 5, 5.0]])
    np.testing.assert_array_equal(store._convergence(t, v, 1.0, None), [4.0, 9.0, np.nan])
    # held for 2 s: the first epoch with 3 good epochs in [t, t + 2]
    np.testing.assert_array_equal(store._convergence(t, v, 1.0, 2.0), [4.0, np.nan, np.nan])
    assert np.isnan(store._convergence(t, np.array([[np.nan] * 10]), 1.0, None)[0])


def test_windows_and_metrics():
    t = np.arange(1.0, 11.0)  # 1..10
    segs = [{"name": "A", "start_s": 0.0, "end_s": 4.0}, {"name": "B", "start_s": 4.0, "end_s": 10.0}]
    stats = StatisticsSpec.model_validate({
        "quantities": ["pos_e", "pos_h"], "metrics": ["std", "rms", "mean", "max"],
        "windows": {"A": {"segment": "A"}, "last3": {"last_s": 3, "metrics": ["rms"]},
                    "late": {"start_s": 8}}})
    states = ("pos_e", "pos_n", "pos_u")
    err = np.zeros((2, 10, 3))
    err[0, :, 0] = np.arange(10.0)  # pos_e = t - 1
    err[1, :, 0] = -1.0
    err[:, :, 1] = 0.0
    sig = np.ones_like(err)
    nees = np.ones((2, 10, 1))
    cols = store.run_statistics(t, err, sig, nees, states, ["pos"], stats, segs)
    np.testing.assert_allclose(cols["mean_A_pos_e_m"], [1.5, -1.0])  # t = 1..4
    np.testing.assert_allclose(cols["std_A_pos_e_m"], [np.std([0, 1, 2, 3]), 0.0])
    np.testing.assert_allclose(cols["max_A_pos_h_m"], [3.0, 1.0])
    np.testing.assert_allclose(cols["rms_last3_pos_e_m"], [np.sqrt(np.mean([49, 64, 81])), 1.0])
    np.testing.assert_allclose(cols["mean_late_pos_e_m"], [8.0, -1.0])  # t = 8, 9, 10
    np.testing.assert_allclose(cols["nees_pos_mean"], [1.0, 1.0])
    assert store.statistic_columns(stats, [("f", states)])[:4] == [
        "std_A_pos_e_m", "std_A_pos_h_m", "rms_A_pos_e_m", "rms_A_pos_h_m"]


def test_epoch_summary():
    rng = np.random.default_rng(0)
    err = rng.normal(size=(5, 4, 2))
    sig = np.full((5, 4, 2), 2.0)
    out = store.epoch_summary(err, sig, np.ones((5, 4, 1)), ("att_e", "att_n"), ["att"])
    np.testing.assert_allclose(out["att_e_deg_mean"], err[:, :, 0].mean(0))
    np.testing.assert_allclose(out["att_e_deg_std"], err[:, :, 0].std(0, ddof=1))
    np.testing.assert_allclose(out["att_n_deg_rms"], np.sqrt((err[:, :, 1] ** 2).mean(0)))
    np.testing.assert_allclose(out["att_n_deg_sigma"], 2.0)
    np.testing.assert_allclose(out["nees_att"], 1.0)


@pytest.mark.parametrize("nan", [False, True])
def test_epoch_summary_equals_nan_functions(nan):
    """The per-epoch summaries are numpy's nan-functions across runs bit for bit, with NaNs (the
    nan-functions themselves) and without (mean/std on the runs' strided columns, no NaN-free copies)."""
    rng = np.random.default_rng(3)
    err = rng.normal(size=(7, 40, 3)) * 10.0 ** rng.uniform(-3, 3, (7, 40, 3))
    sig = np.abs(rng.normal(size=(7, 40, 3)))
    nees = rng.chisquare(3, size=(7, 40, 1))
    if nan:
        err[2, 5, 1] = sig[0, 7, 2] = nees[4, 9, 0] = np.nan
    out = store.epoch_summary(err, sig, nees, ["pos_e", "pos_n", "pos_u"], ["pos"])
    for i, s in enumerate(["pos_e_m", "pos_n_m", "pos_u_m"]):
        e = err[:, :, i]
        want = {"mean": np.nanmean(e, axis=0), "std": np.nanstd(e, axis=0, ddof=1),
                "rms": np.sqrt(np.nanmean(e * e, axis=0)), "sigma": np.nanmean(sig[:, :, i], axis=0)}
        for k, v in want.items():
            assert np.array_equal(out[f"{s}_{k}"], v, equal_nan=True), (s, k)
    assert np.array_equal(out["nees_pos"], np.nanmean(nees[:, :, 0], axis=0), equal_nan=True)
    # a run's NaN is left out of its epoch (not a NaN mean): the nan-functions' path where it must be
    assert np.isfinite(out["pos_n_m_mean"]).all() and np.isfinite(out["nees_pos"]).all()
    if nan:
        assert out["pos_n_m_mean"][5] == np.mean(np.delete(err[:, 5, 1], 2))


def test_run_file_roundtrip_and_corruption(tmp_path):
    res = {"key": "ab" * 32, "point": 0, "run": 3, "imu_samples": 10,
           "timing": {"total_s": 0.1},
           "estimators": {"f": {"time": np.arange(3.0), "error": np.ones((3, 2)), "sigma": np.ones((3, 2)),
                                "nees": np.ones((3, 1)), "states": ["pos_e", "pos_n"], "blocks": ["pos"],
                                "info": {"nodes": 3}}}}
    p = store.save_run(tmp_path, res)
    assert p == tmp_path / "runs" / ("ab" * 8) / "r00003.npz"
    back = store.load_run(p)
    assert back["key"] == res["key"] and back["run"] == 3
    assert back["estimators"]["f"]["states"] == ["pos_e", "pos_n"]
    np.testing.assert_array_equal(back["estimators"]["f"]["error"], np.ones((3, 2)))
    p.write_bytes(p.read_bytes()[:50])
    assert store.load_run(p) is None
    assert store.load_run(tmp_path / "nope.npz") is None


def test_write_json_nan(tmp_path):
    p = store.write_json(tmp_path / "x.json", {"a": float("nan"), "b": np.float64(2.0), "c": [np.inf]})
    assert p.read_text().replace(" ", "").replace("\n", "") == '{"a":null,"b":2.0,"c":[null]}'


@pytest.mark.parametrize("values, kind", [(["a", "b"], "string"), ([1, 2], "int64"), ([1, 2.5], "double"),
                                          ([True, False], "bool"), ([{"type": "x"}, 1], "string")])
def test_sweep_column_types(values, kind):
    assert str(store._sweep_column(values).type) == kind
