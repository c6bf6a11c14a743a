"""Static coarse alignment (levelling, gyrocompassing) and heading from GNSS course."""

from __future__ import annotations

import numpy as np
import pytest

from aidnav.data import ImuData
from aidnav.nav.alignment import coarse_align_static, heading_from_course
from aidnav.nav.earth import earth_rate_n, gravity
from aidnav.nav.rotations import dcm_from_euler

LAT = np.radians(40.0966)
H = 1580.0


def _static_imu(roll, pitch, heading, n=2000, dt=0.01, gyro_noise=0.0, accel_noise=0.0, gyro_bias=0.0,
                seed=0):
    """Error-free (or noisy) increments of an IMU at rest with the given attitude [rad]."""
    c_nb = dcm_from_euler(roll, pitch, heading).T
    f_b = c_nb @ np.array([0.0, 0.0, gravity(LAT, H)])
    w_b = c_nb @ earth_rate_n(LAT) + gyro_bias
    rng = np.random.default_rng(seed)
    t = 1000.0 + dt * np.arange(1, n + 1)
    dth = (w_b + gyro_noise * rng.standard_normal((n, 3))) * dt
    dv = (f_b + accel_noise * rng.standard_normal((n, 3))) * dt
    return ImuData(t, dth, dv, t0=1000.0)


@pytest.mark.parametrize("rph_deg", [(-6.7, 1.8, 0.0), (10.0, -20.0, 135.0), (-170.0, 60.0, 300.0),
                                     (45.0, 0.0, 90.0), (0.0, 0.0, 359.0)])
def test_roll_pitch_heading_error_free(rph_deg):
    r, p, h = np.radians(rph_deg)
    roll, pitch, heading, info = coarse_align_static(_static_imu(r, p, h), LAT, height=H)
    assert roll == pytest.approx(r, abs=1e-9)
    assert pitch == pytest.approx(p, abs=1e-9)
    assert heading is not None, info["heading_reason"]
    assert np.angle(np.exp(1j * (heading - h))) == pytest.approx(0.0, abs=1e-9)
    assert info["heading_reason"] == "ok"
    assert info["f_norm"] == pytest.approx(info["gravity"], rel=1e-12)


def test_sign_convention_right_wing_down():
    # roll +10°: the right wing (x) points down, so at rest the accelerometer x reads −g sin 10°
    imu = _static_imu(np.radians(10.0), 0.0, 0.0)
    f = imu.dv.sum(0) / (imu.time[-1] - imu.t0)
    assert f[0] == pytest.approx(-gravity(LAT, H) * np.sin(np.radians(10.0)))
    roll, pitch, _, _ = coarse_align_static(imu, LAT)
    assert np.degrees(roll) == pytest.approx(10.0) and pitch == pytest.approx(0.0, abs=1e-12)


def test_window_selection():
    imu = _static_imu(0.1, 0.2, 0.3)
    # corrupt the second half: the window must exclude it
    imu.dv[1000:] += 1.0
    roll, pitch, _, info = coarse_align_static(imu, LAT, start=None, stop=imu.time[1000])
    assert roll == pytest.approx(0.1, abs=1e-9) and pitch == pytest.approx(0.2, abs=1e-9)
    assert info["n"] == 1000
    with pytest.raises(ValueError, match="samples"):
        coarse_align_static(imu, LAT, start=5000.0)


def test_heading_rejected_when_gyro_cannot_see_earth_rate():
    # consumer MEMS: 0.05 deg/s noise per sample at 100 Hz and a 0.06 deg/s bias
    imu = _static_imu(0.0, 0.0, np.radians(30.0), n=3000, gyro_noise=np.radians(0.5),
                      gyro_bias=np.radians([0.06, -0.06, 0.1]))
    roll, pitch, heading, info = coarse_align_static(imu, LAT)
    assert heading is None
    assert "not the Earth rate" in info["heading_reason"]
    # noise alone (no bias) but still too much for 5°: rejected by the heading σ
    imu = _static_imu(0.0, 0.0, np.radians(30.0), n=3000, gyro_noise=np.radians(0.05))
    _, _, heading, info = coarse_align_static(imu, LAT)
    assert heading is None and "heading σ" in info["heading_reason"]
    # a known bias bound given by the user counts too
    imu = _static_imu(0.0, 0.0, np.radians(30.0), n=3000)
    _, _, heading, info = coarse_align_static(imu, LAT, gyro_bias_std=np.radians(10.0 / 3600))
    assert heading is None and info["heading_candidate"] == pytest.approx(np.radians(30.0))
    # navigation grade (0.001 deg/s per sample): accepted, within the stated σ
    imu = _static_imu(0.0, 0.0, np.radians(30.0), n=30000, gyro_noise=np.radians(0.001), seed=3)
    _, _, heading, info = coarse_align_static(imu, LAT)
    assert heading is not None
    assert abs(heading - np.radians(30.0)) < 4 * info["heading_std"] < np.radians(5.0)


def test_heading_from_course():
    assert heading_from_course(0.0, 5.0) == pytest.approx(0.0)
    assert heading_from_course(5.0, 0.0) == pytest.approx(np.pi / 2)
    assert heading_from_course(-5.0, 0.0) == pytest.approx(3 * np.pi / 2)
    h = heading_from_course([1.0, -3.0, 0.1], [-1.0, -3.0, 0.1], min_speed=0.5)
    np.testing.assert_allclose(h[:2], np.radians([135.0, 225.0]))
    assert np.isnan(h[2])


# ------------------------------------------------------------------------------------- real data
def test_real_drive_static_alignment(data_dir):
    d = data_dir / "rtklibexplorer_drive_0708"
    if not d.is_dir():
        pytest.skip(f"data set rtklibexplorer_drive_0708 not found in {data_dir}")
    from aidnav.io.logs import read_rtklibexplorer_imu

    imu = read_rtklibexplorer_imu(d / "imu_1934.csv")  # raw sensor axes as RFU, no mounting rotation
    t0 = imu.time[0]
    roll, pitch, heading, info = coarse_align_static(imu, LAT, start=t0, stop=t0 + 30.0, height=H)
    np.testing.assert_allclose(info["mean_f"] / 9.80665, [0.118, 0.032, 1.006], atol=0.002)
    assert np.degrees(roll) == pytest.approx(-6.7, abs=0.3)
    assert np.degrees(pitch) == pytest.approx(1.8, abs=0.3)
    # the gyro bias (0.07 deg/s horizontal, 0.17 deg/s vertical) swamps the 11.5 deg/h Earth rate
    assert heading is None and "not the Earth rate" in info["heading_reason"]
