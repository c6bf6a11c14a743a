"""Velocity against a reference's own positions (issue 40, session 11): an RTKLIB ``.pos`` file written from a
known trajectory, read by :func:`aidnav.io.rtklib.read_pos` (which keeps every velocity at its stamp), scored
by :mod:`aidnav.analysis.velocity_reference` — known answers and closed forms, no filter."""

from __future__ import annotations

import numpy as np
import pytest

from aidnav.analysis.velocity_reference import interval_velocity_errors, velocity_lateness
from aidnav.io.rtklib import read_pos
from aidnav.nav.earth import enu_to_lla

LAT0, LON0, H0 = np.radians(40.0967), np.radians(-105.1472), 1580.0
DT = 0.25  # the reference's interval (4 Hz, as the walk's)
T0 = 408640.0  # GPS seconds of week (Thursday 17:30:40)


def _truth(t):
    """A walker's tangent-plane ENU position [m] and velocity [m/s] at t [s from T0]: 1.2 m/s east with a
    0.7 Hz sway, a slow north meander with a 0.9 Hz bob, 5 cm of vertical bounce (all zero at t = 0)."""
    w1, w2, w3, w4 = 2 * np.pi * np.array([0.7, 0.05, 0.9, 1.0])
    p = np.column_stack([1.2 * t + 0.4 * np.sin(w1 * t), 3.0 * np.sin(w2 * t) + 0.2 * np.sin(w3 * t),
                         0.05 * np.sin(w4 * t)])
    v = np.column_stack([1.2 + 0.4 * w1 * np.cos(w1 * t),
                         3.0 * w2 * np.cos(w2 * t) + 0.2 * w3 * np.cos(w3 * t), 0.05 * w4 * np.cos(w4 * t)])
    return p, v


def _write_pos(path, t, p, v_enu):
    """RTKLIB ``.pos`` (calendar GPST, lat/lon in degrees to 1e-9, height to 0.1 mm, velocity NEU columns)."""
    lat, lon, h = enu_to_lla(p[:, 0], p[:, 1], p[:, 2], LAT0, LON0, H0)
    lines = ["%  GPST                  latitude(deg) longitude(deg)  height(m)   Q  ns   sdn(m)   sde(m)"
             "   sdu(m)  sdne(m)  sdeu(m)  sdun(m) age(s)  ratio  vn(m/s)  ve(m/s)  vu(m/s)  sdvn  sdve"
             "  sdvu"]
    for k in range(t.size):
        s = 17 * 3600 + 30 * 60 + 40.0 + t[k]
        hh, mm, ss = int(s // 3600), int(s % 3600 // 60), s % 60
        lines.append(f"2025/08/28 {hh:02d}:{mm:02d}:{ss:06.3f} {np.degrees(lat[k]):14.9f} "
                     f"{np.degrees(lon[k]):14.9f} {h[k]:10.4f}   1  20   0.0100   0.0100   0.0100"
                     "   0.0000   0.0000   0.0000   0.00    0.0 "
                     f"{v_enu[k, 1]:8.4f} {v_enu[k, 0]:8.4f} {v_enu[k, 2]:8.4f} 0.0300 0.0300 0.0300")
    path.write_text("\n".join(lines) + "\n")


@pytest.fixture(scope="module")
def synthetic(tmp_path_factory):
    """The reference at 4 Hz over 120 s twice — its velocity columns the instantaneous velocity, or the
    backward difference (p_k − p_{k−1})/Δt stamped at t_k (the first epoch: the instantaneous one) — and
    an estimate's true velocity at 150 Hz on stamps that are not the reference's."""
    d = tmp_path_factory.mktemp("pos")
    t = np.arange(0.0, 120.0 + 1e-9, DT)
    p, v = _truth(t)
    back = v.copy()
    back[1:] = np.diff(p, axis=0) / DT
    _write_pos(d / "inst.pos", t, p, v)
    _write_pos(d / "back.pos", t, p, back)
    te = np.arange(0.003, 120.0, 1 / 150)
    return read_pos(d / "inst.pos"), read_pos(d / "back.pos"), T0 + te, te


def test_the_reader_keeps_the_stamp_and_position_differences_score_the_truth_at_zero(synthetic):
    inst, back, t_est, te = synthetic
    assert np.allclose(inst.time - T0, np.arange(inst.time.size) * DT, atol=1e-6)  # stamps unchanged
    _, v_true = _truth(te)
    for ref in (inst, back):  # the positions alone decide: the velocity columns play no part
        iv = interval_velocity_errors(t_est, v_true, ref.time, ref.lat, ref.lon, ref.height)
        assert len(iv) >= 478
        # rounding of the file (1e-9 deg ≈ 0.1 mm, 0.1 mm) over 0.25 s, the trapezoid at 150 Hz: < 1 mm/s
        assert iv.rms_horizontal() < 1e-3 and iv.rms_vertical() < 1e-3
    # the same perfect estimate against the file's backward-difference velocity at its stamps is off by the
    # boxcar's lag: |v(t) − mean v over [t − Δt, t]| ≈ (Δt/2)|a|, here a 0.1 m/s-level RMS
    j = np.searchsorted(t_est, back.time[1:-1])
    off = v_true[j] - back.vel[1:-1]
    assert np.sqrt(np.mean(np.sum(off[:, :2] ** 2, axis=1))) > 0.1


def test_lateness_of_the_velocity_columns_follows_their_definition(synthetic):
    """Instantaneous velocity at the stamp: not late; a backward difference stamped at the interval's end:
    Δt/2 late (a boxcar over [t − Δt, t]: e^{−iπfΔt}·sinc(fΔt), a pure delay of Δt/2)."""
    inst, back, _, _ = synthetic
    for ref, want in ((inst, 0.0), (back, DT / 2)):
        lag, _ = velocity_lateness(ref.time, ref.vel, ref.time, ref.lat, ref.lon, ref.height)
        assert abs(lag - want) < 0.005, (lag, want)


def test_a_late_estimate_is_found_late_by_its_delay(synthetic):
    inst, _, t_est, te = synthetic
    for delay in (0.08, -0.03):
        _, v = _truth(te - delay)  # describes at t what happened at t − delay
        lag, rms = velocity_lateness(t_est, v, inst.time, inst.lat, inst.lon, inst.height)
        assert abs(lag - delay) < 0.002 and rms < 0.01, (delay, lag, rms)
        iv = interval_velocity_errors(t_est, v, inst.time, inst.lat, inst.lon, inst.height)
        assert iv.rms_horizontal() > 0.02  # and the score at zero shift says so


def test_constant_acceleration_backward_difference_closed_form(tmp_path):
    """p = ½at²: the backward difference at t_k is a·(t_k − Δt/2) exactly, linear between stamps, so the
    squared error of the shifted interval means is a parabola in the lag and the refinement is exact."""
    t = np.arange(0.0, 30.0 + 1e-9, DT)
    a = np.array([0.3, -0.2, 0.0])
    p = 0.5 * a * t[:, None] ** 2
    back = a * (t[:, None] - DT / 2)
    _write_pos(tmp_path / "acc.pos", t, p, back)
    ref = read_pos(tmp_path / "acc.pos")
    assert np.allclose(ref.vel[1:], back[1:], atol=5e-5)
    lag, rms = velocity_lateness(ref.time, ref.vel, ref.time, ref.lat, ref.lon, ref.height, step_s=0.01)
    assert abs(lag - DT / 2) < 2e-4 and rms < 2e-3, (lag, rms)


def test_quality_and_gaps_select_the_intervals(synthetic):
    inst, _, t_est, te = synthetic
    _, v = _truth(te)
    use = np.ones(inst.time.size, bool)
    use[[10, 11, 200]] = False  # intervals 10, 11, 12 and 200, 201 lose an end
    iv = interval_velocity_errors(t_est, v, inst.time, inst.lat, inst.lon, inst.height, use=use)
    full = interval_velocity_errors(t_est, v, inst.time, inst.lat, inst.lon, inst.height)
    assert len(full) - len(iv) == 5
    keep = np.r_[0:300, 320:inst.time.size]  # a 5-s gap is not an interval
    gap = interval_velocity_errors(t_est, v, inst.time[keep], inst.lat[keep], inst.lon[keep],
                                   inst.height[keep])
    assert np.all(gap.t_end - gap.t_start < 0.3)


def test_three_cornered_hat_recovers_independent_noises():
    """Three estimates of one random signal with independent errors of σ 0.02, 0.05, 0.04 per axis (20 000
    samples): each σ² recovered within 5 σ of its sampling error (var of a variance estimate ≈ 2σ⁴/n, here
    summed over the three differences); the signal itself cancels."""
    from aidnav.analysis.velocity_reference import three_cornered_hat

    rng = np.random.default_rng(3)
    n = 20000
    truth = rng.normal(0, 1.0, (n, 3)).cumsum(axis=0)
    s = np.array([0.02, 0.05, 0.04])
    a, b, r = (truth + rng.normal(0, si, (n, 3)) for si in s)
    va, vb, vr = three_cornered_hat(a, b, r)
    tol = 5 * np.sqrt(2 / n) * (s[0] ** 2 + s[1] ** 2 + s[2] ** 2)
    for v, si in ((va, s[0]), (vb, s[1]), (vr, s[2])):
        assert np.all(np.abs(v - si**2) < tol), (v, si**2, tol)
    a[::7, 0] = np.nan  # rows with a NaN are left out
    assert np.all(np.isfinite(three_cornered_hat(a, b, r)[2]))
