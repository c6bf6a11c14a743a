"""Self-calibration states of the loose filter (issue 26, item 2): GNSS lever arm, IMU–GNSS time
offset, IMU → vehicle mounting, odometer scale factor.

1. Finite-difference Jacobians of the new H columns (same method and tolerance as
   ``test_measurement_jacobians``: column j of H is −(z(true(+ε e_j)) − z(true(−ε e_j))) / 2ε with the
   engine's feedback b̂ ← b̂ + r).
2. The time-offset column through the motion: a fix taken on a constant-acceleration trajectory at
   GNSS time t_g, and an INS that runs d (the true offset) ahead, give z = H_d (d − d̂) + O(d²).
3. :func:`calibration_summary` names and the layout switches.
"""

from __future__ import annotations

import numpy as np
import pytest

from aidnav.filters import measurements as ms
from aidnav.filters.config import LooseConfig
from aidnav.filters.engine import feedback, node_rates
from aidnav.filters.layout import L_LEVER, L_MOUNT, L_N, L_ODO, L_TOFF, make_layout
from aidnav.filters.loose import loose_layout
from aidnav.filters.measurements.check import check_jacobian
from aidnav.filters.measurements.gnss import W_FN
from aidnav.nav.earth import radii
from aidnav.nav.rotations import dcm_from_euler, dcm_from_quat, quat_from_euler

LAY = make_layout(False, ("odometer_scale", "lever_arm", "time_offset", "mounting"))  # 15 + 1 + 3 + 1 + 3
N = int(LAY[L_N])
W_RAW = np.array([0.05, -0.02, 0.3])
F_N = np.array([0.8, -0.3, 9.9])  # mean specific force, n [m/s²]
STEPS = np.array([1e-4] * 3 + [1e-3] * 3 + [1e-7, 1e-7, 0.5] + [1e-4] * 3 + [1e-3] * 3
                 + [1e-3] + [1e-3] * 3 + [1e-3] + [1e-4] * 3)
LEVER = np.array([0.4, 1.3, -0.9])


def _nominal():
    q = quat_from_euler(0.1, -0.05, 1.0)
    st = np.array([0.6, 2.0, 120.0, 12.0, -5.0, 0.8, *q])
    bias = np.zeros(N - 9)
    bias[0:3] = [1e-3, -2e-3, 5e-4]
    bias[LAY[L_ODO] - 9] = 0.02
    bias[LAY[L_LEVER] - 9:LAY[L_LEVER] - 6] = [0.05, -0.1, 0.2]
    bias[LAY[L_TOFF] - 9] = -0.12
    bias[LAY[L_MOUNT] - 9:LAY[L_MOUNT] - 6] = [0.01, -0.02, 0.03]
    return st, bias


def _nav(st, bias, dt_back, rate_from_bias, bias_nominal):
    C = dcm_from_quat(st[6:10])
    b = bias if rate_from_bias else bias_nominal
    wb = W_RAW - b[0:3]
    w = np.zeros((5, 3))
    node_rates(st, wb, wb * 0.01, 0.01, w)
    w[W_FN] = F_N
    return ms.Nav(st, C, w, dt_back, bias)


def _check(model, row, par, rate_from_bias=True, dt_back=0.0):
    st0, b0 = _nominal()
    def nav_of(st, b):
        return _nav(st, b, dt_back, rate_from_bias, b0)

    return check_jacobian(model, row, par, LAY, st0, b0, nav_of,
                          STEPS, feedback)[0]


def _vehicle_par(lever_sig=0.0):
    p = np.zeros(16)
    V = ms.vehicle
    p[V.V_SIG], p[V.V_MIN_SPEED], p[V.V_LEVER:V.V_LEVER + 3] = 0.1, 1.0, LEVER
    p[V.V_CBV:V.V_CBV + 9] = dcm_from_euler(0.01, -0.02, 1.6).ravel()
    p[V.V_LEVER_SIG] = lever_sig
    return p


def test_gnss_position_lever_and_time_offset_columns():
    H = _check(ms.gnss_position_model, np.array([0.6, 2.0, 100.0, 1.0, 2.0, 3.0]), LEVER, dt_back=0.2)
    assert np.abs(H[:, LAY[L_LEVER]:LAY[L_LEVER] + 3]).max() > 0.5
    assert np.abs(H[:, LAY[L_TOFF]]).max() > 5.0  # ≈ the velocity


def test_gnss_velocity_lever_and_time_offset_columns():
    H = _check(ms.gnss_velocity_model, np.array([11.0, -4.0, 1.0, 0.1, 0.2, 0.3]), LEVER, dt_back=0.05)
    assert np.abs(H[:, LAY[L_TOFF]]).max() > 0.3  # ≈ the acceleration


def test_nhc_mounting_columns():
    H = _check(ms.nhc_model, np.zeros(6), _vehicle_par(), rate_from_bias=False)
    assert np.abs(H[:, LAY[L_MOUNT]:LAY[L_MOUNT] + 3]).max() > 5.0  # ≈ the forward speed


def test_odometer_mounting_and_scale_columns():
    H = _check(ms.odometer_model, np.array([12.5, 0.05, 0, 0, 0, 0]), _vehicle_par(), rate_from_bias=False)
    assert H[0, LAY[L_ODO]] != 0.0


def test_nhc_variance_from_an_unknown_lever_arm():
    """R = σ² + ω_⊥² σ_l² per constrained axis (ω in the vehicle frame)."""
    st, b = _nominal()
    nav = _nav(st, b, 0.0, True, b)
    R0, R1 = np.zeros((6, 6)), np.zeros((6, 6))
    H, z = np.zeros((6, N)), np.zeros(6)
    ms.nhc_model(nav, np.zeros(6), _vehicle_par(0.0), LAY, H, z, R0)
    ms.nhc_model(nav, np.zeros(6), _vehicle_par(0.7), LAY, H, z, R1)
    from aidnav.filters.measurements.vehicle import _w_nb, mounting_dcm

    wv = mounting_dcm(nav, _vehicle_par(), LAY) @ _w_nb(nav)
    assert R1[0, 0] - R0[0, 0] == pytest.approx((wv[1] ** 2 + wv[2] ** 2) * 0.49, rel=1e-12)
    assert R1[1, 1] - R0[1, 1] == pytest.approx((wv[0] ** 2 + wv[1] ** 2) * 0.49, rel=1e-12)


@pytest.mark.parametrize("d_true", [0.08, -0.15])
def test_time_offset_through_the_motion(d_true):
    """Fix at t_g on p(t) = p0 + v0 t + ½ a t² (local ENU, flat Earth to first order), INS at the node
    t_n holding the true state at t_n + d: z = H_d (d − d̂) to O((d − d̂)²) for position and velocity."""
    lat0, lon0, h0 = 0.6, 2.0, 100.0
    rm, rn = radii(lat0)
    v0 = np.array([12.0, -5.0, 0.3])
    a = np.array([0.7, 1.1, -0.05])
    t_g, dt_back, d_hat = 10.0, 0.03, 0.02

    def pos(t):
        p = v0 * t + 0.5 * a * t * t
        return np.array([lat0 + p[1] / (rm + h0), lon0 + p[0] / ((rn + h0) * np.cos(lat0)), h0 + p[2]])

    t_ins = t_g + dt_back + d_true  # the INS at the node time t_g + dt_back is the truth at this time
    q = quat_from_euler(0.0, 0.0, 0.4)
    st = np.array([*pos(t_ins), *(v0 + a * t_ins), *q])
    lay = make_layout(False, ("time_offset",))
    n = int(lay[L_N])
    bias = np.zeros(n - 9)
    bias[lay[L_TOFF] - 9] = d_hat
    w = np.zeros((5, 3))
    node_rates(st, np.zeros(3), np.zeros(3), 0.01, w)
    # specific force that gives the acceleration a: f = a − g + (2Ω_ie + Ω_en) × v
    from aidnav.nav.earth import gravity

    w2 = 2.0 * w[2] + (w[3] - w[2])
    w[W_FN] = a + np.array([0.0, 0.0, gravity(st[0], st[2])]) + np.cross(w2, st[3:6])
    nav = ms.Nav(st, dcm_from_quat(st[6:10]), w, dt_back, bias)
    H, z, R = np.zeros((6, n)), np.zeros(6), np.zeros((6, 6))
    p = pos(t_g)
    ms.gnss_position_model(nav, np.array([*p, 1, 1, 1]), np.zeros(3), lay, H, z, R)
    r = d_true - d_hat
    tb = dt_back + d_hat
    # H uses the velocity at the node, the truth moves between: |a| (|tb| + |r|) |r| + ½ |a| tb² [m]
    an = np.linalg.norm(a)
    tol = an * (abs(tb) + abs(r)) * abs(r) + 0.5 * an * tb * tb + 1e-6
    assert np.all(np.abs(z[:3] - H[:3, lay[L_TOFF]] * r) <= tol)
    assert np.linalg.norm(H[:3, lay[L_TOFF]] * r) > 10 * tol  # the column carries the offset
    vg = v0 + a * t_g
    ms.gnss_velocity_model(nav, np.array([*vg, 1, 1, 1]), np.zeros(3), lay, H, z, R)
    assert np.allclose(z[:3], H[:3, lay[L_TOFF]] * r, atol=2e-3 * abs(r) + 1e-6)  # exact for constant a


def test_layout_switches():
    cfg = LooseConfig()
    lay = loose_layout(cfg)
    assert lay[L_LEVER] >= 0 and lay[L_TOFF] >= 0 and lay[L_MOUNT] < 0  # mounting needs NHC or odometer
    assert loose_layout(cfg, gnss_velocity=False)[L_TOFF] < 0  # automatic: the offset needs GNSS velocity
    given = LooseConfig.model_validate({"gnss": {"lever_arm_m": [0, 0, 1]}, "imu": {"time_offset_s": 0.1}})
    assert loose_layout(given)[L_LEVER] < 0 and loose_layout(given)[L_TOFF] < 0  # given values are known
    on = LooseConfig.model_validate({"gnss": {"lever_arm_m": [0, 0, 1]}, "calibration": {"lever_arm": True}})
    assert loose_layout(on)[L_LEVER] >= 0
    cfg = LooseConfig.model_validate({"constraints": {"nhc": True}})
    assert loose_layout(cfg)[L_MOUNT] >= 0
    cfg = LooseConfig.model_validate({"constraints": {"nhc": True}, "calibration": {
        "time_offset": False, "lever_arm": False, "mounting": False}})
    lay = loose_layout(cfg)
    # the INS block only: the default IMU model's 27 states (config.DEFAULT_IMU)
    assert lay[L_LEVER] < 0 and lay[L_TOFF] < 0 and lay[L_MOUNT] < 0 and lay[L_N] == 27


def test_calibration_summary_names_and_mounting_round_trip():
    """Zero estimates give back the configured values; a mounting residual about the vehicle's up axis
    changes the summary's heading by that angle (sign: ρ_z = −Δheading)."""
    from aidnav.filters.result import FilterResult, calibration_summary

    lay = make_layout(False, ("lever_arm", "time_offset", "mounting"))
    n = int(lay[L_N])
    bias = np.zeros((1, n - 9))
    pdiag = np.full((1, n), 1e-4)
    base = {"time_offset_s": 0.05, "lever_arm_m": [0.1, 0.2, 0.3], "mounting_rph_deg": [1.0, -2.0, 30.0]}
    r = FilterResult(np.zeros(1), np.zeros((1, 10)), bias, pdiag, np.zeros(1), layout=lay,
                     calibration_base=base)
    c = calibration_summary(r)
    assert c["time_offset_s"]["value"] == 0.05 and c["time_offset_s"]["std"] == pytest.approx(0.01)
    assert np.allclose(c["lever_arm_m"]["value"], [0.1, 0.2, 0.3])
    assert np.allclose(c["mounting_rph_deg"]["value"], [1.0, -2.0, 30.0])
    assert c["odometer_scale"] == {"value": 0.0, "std": None, "estimated": False}
    bias[0, lay[L_MOUNT] - 9 + 2] = np.radians(0.5)
    h = calibration_summary(r)["mounting_rph_deg"]["value"][2]
    assert abs(abs(h - 30.0) - 0.5) < 0.02


def test_presets():
    from aidnav.filters.presets import apply_preset, preset_names

    assert preset_names() == ["aircraft", "car", "pedestrian", "ship"]
    car = apply_preset(None, "car")
    assert car.constraints.nhc and car.constraints.nhc_lever_arm_sigma_m == 1.0
    assert loose_layout(car)[L_MOUNT] >= 0
    for name in ("aircraft", "pedestrian", "ship"):
        assert not apply_preset(None, name).constraints.nhc
    assert not apply_preset(None, "ship").constraints.zupt
    # an explicit configuration key wins over the preset
    mine = LooseConfig.model_validate({"constraints": {"nhc_sigma_m_s": 0.2}})
    c = apply_preset(mine, "car")
    assert c.constraints.nhc and c.constraints.nhc_sigma_m_s == 0.2
    assert apply_preset(mine, None) is mine
    with pytest.raises(ValueError, match="known: aircraft, car"):
        apply_preset(None, "boat")


def test_gnss_position_error_states():
    """Gauss-Markov fix errors b: z = (p̂_ant + b̂) − fix, so z moves by b̂ and H[:, b] = −I."""
    from aidnav.filters.layout import L_GPE

    lay = make_layout(False, ("gnss_pos_error",))
    n = int(lay[L_N])
    st, _ = _nominal()
    bias = np.zeros(n - 9)
    w = np.zeros((5, 3))
    node_rates(st, W_RAW, W_RAW * 0.01, 0.01, w)
    row = np.array([0.6, 2.0, 100.0, 1.0, 1.0, 1.0])
    H, z0, R = np.zeros((6, n)), np.zeros(6), np.zeros((6, 6))
    ms.gnss_position_model(ms.Nav(st, dcm_from_quat(st[6:10]), w, 0.0, bias), row, LEVER, lay, H, z0, R)
    assert np.array_equal(H[:3, lay[L_GPE]:lay[L_GPE] + 3], -np.eye(3))
    bias[lay[L_GPE] - 9:lay[L_GPE] - 6] = [0.3, -0.2, 0.5]
    z1 = np.zeros(6)
    ms.gnss_position_model(ms.Nav(st, dcm_from_quat(st[6:10]), w, 0.0, bias), row, LEVER, lay, H, z1, R)
    assert np.allclose(z1[:3] - z0[:3], [0.3, -0.2, 0.5], atol=1e-9)


def test_summary_calibration_reads_the_layout():
    """Calibration states after a 15-state INS block are not reported as scale factors."""
    from aidnav.filters.result import FilterResult, summary_calibration

    lay = make_layout(False, ("lever_arm", "time_offset", "mounting"))
    n = int(lay[L_N])
    bias = np.zeros((1, n - 9))
    bias[0, 0] = np.radians(1.0) / 3600.0
    r = FilterResult(np.zeros(1), np.zeros((1, 10)), bias, np.full((1, n), 1e-6), np.zeros(1), layout=lay)
    c = summary_calibration(r, {"time_offset_s": -0.1})
    assert c["gyro_bias_x_deg_h"]["value"] == pytest.approx(1.0)
    assert not any("_sf_" in k for k in c)
    assert c["time_offset_s"]["value"] == pytest.approx(-0.1) and c["time_offset_s"]["estimated"]
