"""The loose filter chunk by chunk (:mod:`aidnav.filters.stream`) gives the whole-log result
(:func:`aidnav.filters.loose.run_loose`) number for number: forward, smoothed, with ZUPT/static flags,
an automatic initialisation with a course alignment, a time-offset state and a bridged IMU gap, in
chunks far smaller than the log."""

from __future__ import annotations

import numpy as np
import pytest

from aidnav.data import ImuData
from aidnav.filters.engine import Output, run_chunk, run_filter, start_carry
from aidnav.filters.layout import L_TOFF
from aidnav.filters.loose import run_loose
from aidnav.filters.stream import needs_whole_log, stream_loose
from aidnav.filters.tuning import loose_config_from_specs, perturbed_initial_state
from aidnav.sim.gnss import GnssSpec, simulate_gnss
from aidnav.sim.imu import ImuSpec, corrupt_imu
from aidnav.sim.scenario import parse_scenario
from aidnav.sim.trajectory import generate_truth


def _log(static_s=0.0, seed=3):
    segs = ([dict(type="static", duration_s=static_s),
             dict(type="accelerate", to_speed_m_s=10.0, duration_s=5)] if static_s else []) + [
        dict(type="straight", duration_s=40), dict(type="turn", angle_deg=90, rate_deg_s=6),
        dict(type="s_turns", duration_s=60, amplitude_deg=20), dict(type="straight", duration_s=20)]
    sc = parse_scenario(dict(name="stream", seed=seed, imu_rate_hz=50.0,
                             initial=dict(lat_deg=30.0, lon_deg=114.0, height_m=50.0, heading_deg=30.0,
                                          speed_m_s=0.0 if static_s else 10.0), segments=segs))
    truth, imu_true, _ = generate_truth(sc)
    spec = ImuSpec.from_units(gyro_bias_deg_h=10.0, arw_deg_sqrt_h=0.2, accel_bias_ug=500.0,
                              vrw_m_s_sqrt_h=0.05, bias_corr_time_s=np.inf)
    gs = GnssSpec(rate_hz=1.0, sigma_pos_enu=[0.5, 0.5, 1.0], sigma_vel_enu=[0.05, 0.05, 0.1])
    rng = np.random.default_rng(seed)
    imu, _ = corrupt_imu(imu_true, spec, rng)
    gnss = simulate_gnss(truth, gs, rng)
    lla, vel, rph = perturbed_initial_state(truth, rng)
    return truth, imu, gnss, spec, gs, (lla, vel, rph)


def _chunks(imu, size):
    for a in range(0, len(imu), size):
        b = min(a + size, len(imu))
        t0 = imu.t0 if a == 0 else float(imu.time[a - 1])
        yield ImuData(imu.time[a:b], imu.dtheta[a:b], imu.dv[a:b], t0=t0)


def _streamed(imu, gnss, cfg, size, **kw):
    fwd, sm = [], []

    def emit(p, forward=False):
        (fwd if forward or not p.smoothed else sm).append(p)

    res = stream_loose(_chunks(imu, size), gnss, cfg, emit, head_s=5.0, **kw)
    cat = {k: (np.concatenate([getattr(p, k) for p in ps]) if ps else None)
           for ps, k in ((fwd, "time"), (fwd, "state"), (fwd, "bias"), (fwd, "pdiag"))}
    if sm:
        cat.update({"s_" + k: np.concatenate([getattr(p, k) for p in sm]) for k in ("state", "pdiag")})
    return res, cat


def _same(a, b):
    assert a.shape == b.shape
    np.testing.assert_allclose(a, b, rtol=0, atol=1e-12)


@pytest.fixture(scope="module")
def given_init():
    truth, imu, gnss, spec, gs, (lla, vel, rph) = _log(static_s=10.0)
    cfg = loose_config_from_specs(spec, gs, init_rph_deg=rph, init_lla_deg_m=lla, init_vel=vel)
    return imu, gnss, cfg


def test_engine_chunks_equal_one_call(given_init):
    """run_chunk over pieces with the carry = run_filter in one call (every output, node and log row)."""
    from aidnav.filters.loose import Imu, loose_setup

    imu, gnss, cfg = given_init
    su = loose_setup(imu, gnss, cfg, None, [])
    n = len(imu)
    z = np.zeros(n, np.bool_)
    whole = Imu(su.t_imu, imu.dtheta, imu.dv, z, np.zeros((n, 2)), np.zeros((0, 2)))
    out = Output(3, True, np.zeros(0, np.int64))
    r1 = run_filter(whole, su.rec, su.models, su.proc, su.ini, out)
    cy = start_carry(su.rec, su.proc, su.ini, False)
    parts = []
    for a in range(0, n, 777):
        b = min(n, a + 777)
        cy = cy._replace(last=b == n)
        r = run_chunk(Imu(su.t_imu[a:b], imu.dtheta[a:b], imu.dv[a:b], z[a:b], np.zeros((b - a, 2)),
                          np.zeros((0, 2))), su.rec, su.models, su.proc, su.ini, out, cy)
        cy = r.carry
        parts.append(r)
    for f in ("out_idx", "out_st", "out_bias", "out_pdiag", "out_node", "node_idx", "S_post", "S_prior",
              "S_phi", "S_dx"):
        got = np.concatenate([getattr(p, f) for p in parts])
        np.testing.assert_array_equal(got, getattr(r1, f), err_msg=f)
    M = len(su.rec.t)
    np.testing.assert_array_equal(r1.st, cy.st)
    np.testing.assert_array_equal(r1.P, cy.P)
    np.testing.assert_array_equal(r1.log.status[:M], np.max([p.log.status[:M] for p in parts], axis=0))


@pytest.mark.parametrize("smooth", [False, True])
def test_stream_equals_whole_log(given_init, smooth):
    imu, gnss, cfg = given_init
    cfg = cfg.model_copy(update={"constraints": cfg.constraints.model_copy(update={"zupt": True})})
    assert not needs_whole_log(cfg)
    withheld = (gnss.time >= 60) & (gnss.time < 80)
    ref = run_loose(imu, gnss, cfg, withheld=withheld, smooth=smooth)
    res, cat = _streamed(imu, gnss, cfg, 1000, withheld=withheld, smooth=smooth)  # ≈ 20 s chunks of 140 s
    assert ref.counts["static_samples"] > 0 and res.counts == ref.counts
    if smooth:
        _same(cat["time"], ref.time)
        _same(cat["state"], ref.forward_state)
        _same(cat["s_state"], ref.state)
        _same(cat["s_pdiag"], ref.pdiag)
    else:
        _same(cat["time"], ref.time)
        _same(cat["state"], ref.state)
        _same(cat["bias"], ref.bias)
        _same(cat["pdiag"], ref.pdiag)
    for k, v in ref.records.items():
        np.testing.assert_array_equal(res.records[k], v, err_msg=k)
    np.testing.assert_array_equal(res.final_P, ref.final_P)
    # the per-record log (each chunk's engine call saw only the records it could reach): the record rows
    # of the whole-log run, nu and s in their first REC_ROWS columns (the rest unused by records)
    M = len(res.innovations["t"])
    for k in ("t", "model", "status", "nis", "reinit", "ref"):
        np.testing.assert_array_equal(res.innovations[k], ref.innovations[k][:M], err_msg=k)
    for k in ("nu", "s"):
        w = res.innovations[k].shape[1]
        np.testing.assert_array_equal(res.innovations[k], ref.innovations[k][:M, :w], err_msg=k)
        assert np.isnan(ref.innovations[k][:M, w:]).all()
    assert (res.innovations["status"] == 1).sum() > 100


def test_stream_automatic_init_time_offset_and_gap():
    """Automatic initialisation (first fix, course alignment found in a later chunk), the IMU–GNSS
    time-offset state (outputs shifted by its final estimate: spooled) and a bridged IMU gap."""
    truth, imu, gnss, spec, gs, _ = _log(seed=5)
    keep = np.ones(len(imu), bool)
    keep[3000:3010] = False  # a 0.2 s gap at 60 s
    imu = ImuData(imu.time[keep], imu.dtheta[keep], imu.dv[keep], t0=imu.t0)
    cfg = loose_config_from_specs(spec, gs)
    cfg = cfg.model_copy(update={"init": cfg.init.model_copy(update={"mode": "auto"}),
                                 "calibration": cfg.calibration.model_copy(update={"time_offset": True})})
    ev_ref, ev = [], []
    ref = run_loose(imu, gnss, cfg, events=ev_ref)
    res, cat = _streamed(imu, gnss, cfg, 700, events=ev)
    assert any("IMU gap" in e for e in ev_ref) and ref.layout[L_TOFF] >= 0
    assert sorted(ev) == sorted(ev_ref)
    _same(cat["time"], ref.time)
    _same(cat["state"], ref.state)
    _same(cat["pdiag"], ref.pdiag)
    assert res.counts == ref.counts


@pytest.mark.parametrize("smooth, engine_rows", [(False, None), (True, None), (True, 777)])
def test_one_chunk_is_the_whole_log_filter(smooth, engine_rows, monkeypatch):
    """The log as one chunk (what ``aidnav process`` runs on a log in memory or any file but interchange
    Parquet) is run_loose bit for bit, also where the head's statistics would differ from the whole
    log's: 50 Hz for 40 s, then 25 Hz (increments of sample pairs joined: the whole log's median interval
    is 0.04 s, the first minute's 0.02 s), a 0.2-s gap, automatic initialisation, the time-offset state
    (outputs spooled and shifted) and, with ``smooth``, the spooled RTS pass. With ``engine_rows`` the
    chunk is run in engine calls of that many samples (:data:`aidnav.filters.stream.ENGINE_ROWS`: a long
    chunk's memory bounded), the head statistics still the whole chunk's: the same numbers."""
    import aidnav.filters.stream as fs

    if engine_rows:
        monkeypatch.setattr(fs, "ENGINE_ROWS", engine_rows)
    truth, imu, gnss, spec, gs, _ = _log(seed=5)
    k = 2000 + (len(imu) - 2000) // 2 * 2
    time = np.concatenate([imu.time[:2000], imu.time[2001:k:2]])
    dth = np.concatenate([imu.dtheta[:2000], imu.dtheta[2000:k:2] + imu.dtheta[2001:k:2]])
    dv = np.concatenate([imu.dv[:2000], imu.dv[2000:k:2] + imu.dv[2001:k:2]])
    keep = np.ones(len(time), bool)
    keep[3000:3005] = False  # a 0.2 s gap at 120 s
    imu = ImuData(time[keep], dth[keep], dv[keep], t0=imu.t0)
    cfg = loose_config_from_specs(spec, gs)
    cfg = cfg.model_copy(update={"init": cfg.init.model_copy(update={"mode": "auto"}),
                                 "calibration": cfg.calibration.model_copy(update={"time_offset": True})})
    ev_ref, ev = [], []
    ref = run_loose(imu, gnss, cfg, events=ev_ref, smooth=smooth)
    res, cat = _streamed(imu, gnss, cfg, len(imu), events=ev, smooth=smooth)
    assert any("IMU gap" in e for e in ev_ref) and ref.layout[L_TOFF] >= 0
    assert ev == ev_ref and res.counts == ref.counts
    np.testing.assert_array_equal(cat["time"], ref.time)
    np.testing.assert_array_equal(cat["state"], ref.forward_state if smooth else ref.state)
    np.testing.assert_array_equal(cat["pdiag"], ref.forward_pdiag if smooth else ref.pdiag)
    if smooth:
        np.testing.assert_array_equal(cat["s_state"], ref.state)
        np.testing.assert_array_equal(cat["s_pdiag"], ref.pdiag)
    np.testing.assert_array_equal(res.final_P, ref.final_P)


def test_stream_smoother_blocks_of_spooled_nodes(given_init, monkeypatch):
    """The RTS pass over node matrices read back from disk in blocks (of 7 nodes here, so that many block
    boundaries fall inside the log) gives the smoothed solution of run_loose number for number."""
    import aidnav.filters.stream as fs

    imu, gnss, cfg = given_init
    ref = run_loose(imu, gnss, cfg, smooth=True)
    monkeypatch.setattr(fs, "RTS_BLOCK", 7)
    res, cat = _streamed(imu, gnss, cfg, 1000, smooth=True)
    assert res.counts == ref.counts and res.counts["nodes"] > 10 * 7  # many block boundaries
    _same(cat["s_state"], ref.state)
    _same(cat["s_pdiag"], ref.pdiag)


def test_record_log_widens_for_wider_records():
    """A record row with more than REC_ROWS innovation rows widens nu and s (no value dropped)."""
    from aidnav.filters.engine import Log, Records
    from aidnav.filters.measurements import MAX_ROWS
    from aidnav.filters.stream import REC_ROWS, _keep_rows, _new_rec_log

    rec = Records(np.arange(10.0), np.zeros(10, np.int64), np.zeros((10, 6)), np.ones(10, bool))
    rl = _new_rec_log(rec)
    assert rl["nu"].shape == (10, REC_ROWS)
    cap = 4  # the chunk's log: records 3..6 (window base 3)
    log = Log(np.zeros(cap), np.zeros(cap, np.int8), np.ones(cap, np.int8), np.arange(cap, dtype=float),
              np.full((cap, MAX_ROWS), np.nan), np.full((cap, MAX_ROWS), np.nan), np.zeros(cap, np.int64),
              np.zeros(cap, np.int8))
    log.nu[1, :3] = [1.0, 2.0, 3.0]
    _keep_rows(rl, log, 3, 5, 3)
    assert rl["nu"].shape == (10, REC_ROWS) and rl["nu"][4, 2] == 3.0
    assert list(rl["status"][2:6]) == [-1, 1, 1, -1]
    log.nu[2, 4] = 5.0
    _keep_rows(rl, log, 5, 7, 3)
    assert rl["nu"].shape == (10, MAX_ROWS) and rl["s"].shape == (10, MAX_ROWS)
    assert rl["nu"][5, 4] == 5.0 and rl["nu"][4, 2] == 3.0 and np.isnan(rl["nu"][4, 4])
    np.testing.assert_array_equal(rl["nis"][3:7], [0.0, 1.0, 2.0, 3.0])
