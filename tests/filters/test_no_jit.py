"""The whole filter runs as plain Python (issue 36, item 4): ``aidnav process`` on a short simulated log
with ``NUMBA_DISABLE_JIT=1`` (every kernel, the model dispatch included, interpreted: a debugger can step
through the engine) gives the JIT's trajectory to 1e-9 (relative; the two differ only in the last bits of
libm/LLVM transcendental functions).

A 40-s car drive (parked 10 s, then turning), MEMS IMU at 50 Hz, 1 Hz GNSS and magnetometer heading,
smoothed: the engine's loop, gate, feedback, self-calibration, the RTS pass and the aids' dispatch.
"""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

from aidnav.io.interchange import read_trajectory, write_gnss, write_imu
from aidnav.sim.gnss import GnssSpec, simulate_gnss
from aidnav.sim.imu import ImuSpec, corrupt_imu
from aidnav.sim.magnetometer import simulate_mag_heading
from aidnav.sim.scenario import parse_scenario
from aidnav.sim.trajectory import generate_truth

COLUMNS = ("lat", "lon", "height", "vel", "rph", "std_pos", "std_vel", "std_att")


@pytest.fixture(scope="module")
def log(tmp_path_factory):
    d = tmp_path_factory.mktemp("nojit")
    truth, imu_true, _ = generate_truth(parse_scenario(dict(
        name="short", seed=1, imu_rate_hz=50.0,
        initial=dict(lat_deg=30.0, lon_deg=114.0, height_m=50.0, speed_m_s=0.0, heading_deg=60.0),
        segments=[dict(type="static", duration_s=10), dict(type="accelerate", duration_s=5, to_speed_m_s=10),
                  dict(type="turn", angle_deg=90, rate_deg_s=9), dict(type="straight", duration_s=15)])))
    rng = np.random.default_rng(36)
    spec = ImuSpec.from_units(gyro_bias_deg_h=10.0, arw_deg_sqrt_h=0.3, accel_bias_ug=1000.0,
                              vrw_m_s_sqrt_h=0.1)
    write_imu(corrupt_imu(imu_true, spec, rng)[0], d / "imu.csv")
    gs = GnssSpec(rate_hz=1.0, sigma_pos_enu=[0.5, 0.5, 1.0], sigma_vel_enu=[0.05, 0.05, 0.1])
    write_gnss(simulate_gnss(truth, gs, rng), d / "gnss.csv")
    mag = simulate_mag_heading(truth, 1.0, 1.0, rng)
    np.savetxt(d / "mag.csv", np.column_stack([mag.time, np.degrees(mag.heading)]), delimiter=",",
               header="time_s,heading_deg", comments="", fmt="%.9f")
    return d


def _process(d, out, disable_jit, *extra):
    env = dict(os.environ, NUMBA_DISABLE_JIT="1" if disable_jit else "0", AIDNAV_KERNELS="jit")
    p = subprocess.run([sys.executable, "-m", "aidnav", "process", "--imu", str(d / "imu.csv"), "--gnss",
                        str(d / "gnss.csv"), "--aid", f"mag={d / 'mag.csv'}", "-o", str(d / out),
                        "--no-figures", "--format", "parquet", *extra], env=env, capture_output=True,
                       text=True, timeout=900)
    assert p.returncode == 0, p.stderr
    return read_trajectory(d / out / "trajectory.parquet")


def test_plain_python_gives_the_jit_result(log):
    py = _process(log, "py", True, "--smooth")  # the forward pass, then the RTS pass over its nodes
    jit = _process(log, "jit", False, "--smooth")
    assert len(py.time) == len(jit.time) > 1500
    # (the output times carry the estimated IMU time offset: the same to the last bits)
    np.testing.assert_allclose(py.time, jit.time, rtol=0, atol=1e-9)
    for c in COLUMNS:
        a, b = getattr(py, c), getattr(jit, c)
        np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-12, err_msg=c)
