"""The filter engine's shared pieces: the gate policy, the innovation log, the result type, the readers
of the odometer and barometer columns."""

from __future__ import annotations

import numpy as np
import pytest

from aidnav.filters import measurements as ms
from aidnav.filters.engine import Log, Models, Work
from aidnav.filters.gate import gated_update
from aidnav.filters.layout import L_BARO, L_N, L_ODO, layout_names, make_layout
from aidnav.io.aux_sensors import read_baro_csv, read_odometer_csv
from aidnav.io.errors import DataError


def _log(cap):
    R = ms.MAX_ROWS
    return Log(np.full(cap, np.nan), np.full(cap, -1, np.int8), np.full(cap, -1, np.int8),
               np.full(cap, np.nan), np.full((cap, R), np.nan), np.full((cap, R), np.nan),
               np.full(cap, -1, np.int64))


def test_gate_policy_rejects_then_gives_up_after_max_consecutive():
    """χ²(1) gate 9 on model 0 with max_rej 2: two outliers rejected, the third accepted ungated, then
    the counter restarts; NIS = ν²/S for one row; the state is unchanged by a rejected update."""
    n = 2
    mod = Models(np.zeros((ms.N_MODELS, 1)), np.zeros((ms.N_MODELS, ms.MAX_ROWS + 1)),
                 np.full(ms.N_MODELS, 2, np.int64), np.zeros((0, 2), np.int64))
    mod.gate[0, 1] = 9.0
    rej = np.zeros(ms.N_MODELS, np.int64)
    log = _log(5)
    P = np.eye(n)
    x = np.zeros(n)
    wk = Work(np.zeros((ms.MAX_ROWS, n)), np.zeros(ms.MAX_ROWS), np.zeros((ms.MAX_ROWS, ms.MAX_ROWS)))
    wk.H[0, 0], wk.R[0, 0] = 1.0, 1.0
    status = []
    for i, zi in enumerate([10.0, 10.0, 10.0, 10.0, 5.5]):
        wk.z[0] = zi
        x_before, P_before = x.copy(), P.copy()
        ok = gated_update(x, P, wk, 1, 0, mod, rej, log, i)
        status.append(int(log.status[i]))
        S = P_before[0, 0] + 1.0
        assert log.s[i, 0] == pytest.approx(S) and log.nu[i, 0] == pytest.approx(zi - x_before[0])
        assert log.nis[i] == pytest.approx(log.nu[i, 0] ** 2 / S)
        if not ok:
            assert np.array_equal(x, x_before) and np.array_equal(P, P_before)
    # third accepted by the rule (x → 5, P → 0.5); the fourth (ν = 5, S = 1.5, NIS 16.7) rejected again;
    # the fifth (ν = 0.5) accepted and the counter restarts
    assert status == [0, 0, 1, 0, 1] and rej[0] == 0


def test_layout_names_and_blocks():
    lay = make_layout(False, ("odometer_scale", "baro_bias"))
    assert lay[L_N] == 17 and lay[L_ODO] == 15 and lay[L_BARO] == 16
    names = layout_names(lay)
    assert len(names) == 17 and names[15] == "odometer_scale" and names[16] == "baro_bias"
    assert make_layout(True, ("clock",))[L_N] == 23
    assert len(layout_names(make_layout(True, ("lever_arm",)))) == 24
    with pytest.raises(ValueError, match="unknown calibration state"):
        make_layout(False, ("wheel",))
    with pytest.raises(ValueError, match="twice"):
        make_layout(False, ("baro_bias", "baro_bias"))


def test_aux_readers(tmp_path):
    p = tmp_path / "odo.csv"
    p.write_text("time_s,speed_km_h\n1.0,36\n1.1,72\n")
    o = read_odometer_csv(p)
    assert np.allclose(o.speed, [10.0, 20.0]) and o.std is None
    b = tmp_path / "baro.csv"
    b.write_text("time_s,height_ft,height_std_m\n1.0,100,0.5\n2.0,200,0.5\n")
    r = read_baro_csv(b)
    assert np.allclose(r.height, [30.48, 60.96]) and np.allclose(r.std, 0.5)
    bad = tmp_path / "bad.csv"
    bad.write_text("time_s,speed_m_s\n1.0,3\n1.1,x\n")
    with pytest.raises(DataError, match=r"bad.csv:3"):
        read_odometer_csv(bad)
    back = tmp_path / "back.csv"
    back.write_text("time_s,height_m\n2.0,3\n1.0,4\n")
    with pytest.raises(DataError, match="does not increase"):
        read_baro_csv(back)
    with pytest.raises(DataError, match="none of the columns"):
        read_baro_csv(p)


def _subset_case():
    """A 60-s MEMS car run as engine inputs (loose records, no node constraints) with IMU-gap variance
    at a few samples, a heading hold until a re-initialisation event that resets heading, velocity and
    position (the fix's velocity is 2 m/s off the INS's)."""
    from aidnav.filters import engine as eng
    from aidnav.filters.config import LooseConfig
    from aidnav.filters.loose import _models, _records, gnss_arrays, initial_covariance, process_noise
    from aidnav.nav.rotations import quat_from_euler
    from aidnav.sim.run import simulate
    from aidnav.sim.scenario import Scenario

    scn = Scenario.model_validate(dict(
        name="subset", seed=3, initial=dict(lat_deg=39.9, lon_deg=116.4, height_m=50.0, heading_deg=60.0),
        imu_rate_hz=100.0, transition_s=2.0,
        segments=[dict(type="accelerate", duration_s=10, to_speed_m_s=10),
                  dict(type="straight", duration_s=20), dict(type="turn", angle_deg=90, rate_deg_s=6),
                  dict(type="straight", duration_s=15)],
        sensors=dict(imu=dict(grade="mems"), gnss=dict(rate_hz=1.0))))
    sim = simulate(scn, seed=5)
    tr, imu = sim.truth, sim.imu
    cfg = LooseConfig()
    rec, _ = _records(cfg, gnss_arrays(sim.gnss, cfg), np.ones(len(sim.gnss), bool), ())
    mod = _models(cfg)._replace(node=np.zeros((0, 2), np.int64))
    n = len(imu)
    gap = np.zeros((n, 2))
    gap[[500, 1800, 3700], 0], gap[[500, 1800, 3700], 1] = 1e-5, 1e-2
    imu_in = eng.Imu(np.asarray(imu.time, float), imu.dtheta, imu.dv, np.zeros(n, np.bool_), gap,
                     np.zeros((0, 2)))
    q = quat_from_euler(*tr.rph[0])
    st0 = np.array([tr.lat[0], tr.lon[0], tr.height[0], *tr.vel[0], *q])
    P0 = initial_covariance(cfg, 15, tr.lat[0], tr.height[0], np.radians([1.0, 1.0, 90.0]))  # φ_U var 2.47
    # re-initialisation: heading from a "course"; the fix's velocity 0.2 m/s off, within 3σ of the fix, so
    # the velocity is kept (issue 35: a larger offset resets velocity and position from the fix, and the
    # permuted filter then diverges numerically after ~25 s where the full one does not: P after that reset
    # is ill-conditioned, position 2e-14 rad² against heading 0.1 rad²)
    k = 2500
    j = int(np.searchsorted(tr.time, imu.time[k]))
    reset_nav = np.array([tr.vel[j, 0] + 0.2, tr.vel[j, 1], tr.vel[j, 2], tr.lat[j], tr.lon[j], tr.height[j],
                          0.1, 0.1, 0.1, 1.0, 1.0, 2.0, 0.0, 0.0, 0.0])
    ini = eng.Init(float(imu.t0), st0, np.zeros(6), P0, k, float(tr.rph[j, 2]), np.radians(2.0), reset_nav)
    taus = np.array([3600.0, 3600.0, 0.0, 0.0])
    proc = eng.Process(make_layout(), process_noise(cfg, 15), taus, np.zeros(0), 1.0)
    return eng, imu_in, rec, mod, proc, ini


def test_state_subset_uses_its_own_indices():
    """A state subset that holds every INS state in another order is the full filter with its states
    permuted: same trajectory, same variances (permuted). The IMU-gap variance, the heading hold and the
    re-initialisation event act on the states by name, through the subset's index map."""
    eng, imu_in, rec, mod, proc, ini = _subset_case()
    out = eng.Output(1, False, np.zeros(0, np.int64))
    full = eng.run_filter(imu_in, rec, mod, proc, ini, out)
    sub = np.random.default_rng(1).permutation(15).astype(np.int64)
    assert sub[2] != 2 and sub[0] != 0
    ini_s = ini._replace(P=ini.P[np.ix_(sub, sub)].copy())
    part = eng.run_filter(imu_in, rec, mod, proc._replace(sub=sub), ini_s, out)
    assert full.reset_node > 0 and part.reset_node == full.reset_node
    np.testing.assert_allclose(part.out_st[:, :3], full.out_st[:, :3], rtol=0, atol=1e-11)  # ~0.1 mm
    np.testing.assert_allclose(part.out_st[:, 3:], full.out_st[:, 3:], rtol=0, atol=1e-7)
    np.testing.assert_allclose(part.out_bias, full.out_bias, rtol=1e-6, atol=1e-12)
    np.testing.assert_allclose(part.out_pdiag, full.out_pdiag[:, sub], rtol=1e-6, atol=0)
    # the events did act: φ_U held at its initial variance until the reset, then the course's σ²
    pu = full.out_pdiag[:, 2]
    assert np.all(pu[:2400] == ini.P[2, 2]) and pu[2500] == pytest.approx(np.radians(2.0) ** 2, rel=1e-2)
