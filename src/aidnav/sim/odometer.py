"""Odometer simulation from a truth trajectory: s = (1 + k) v_y^v + white noise.

v^v = C_b^v (C_n^b v^n + ω_nb^b × l) is the velocity of the wheel point (lever ``lever_b`` from the
IMU, body RFU [m]) in the vehicle frame (RFU, C_b^v from the mounting roll, pitch, heading); v_y^v is
its forward component. ω_nb^b is needed only with a lever arm (``omega_nb_b`` at the truth samples).
"""

from __future__ import annotations

import numpy as np

from aidnav.io.aux_sensors import OdometerData
from aidnav.nav.rotations import dcm_from_euler, dcm_from_quat, euler_to_quat_batch


def simulate_odometer(truth, rate_hz: float, scale_factor: float, sigma_m_s: float, rng: np.random.Generator,
                      mounting_rph_rad=(0.0, 0.0, 0.0), lever_b=None, omega_nb_b=None) -> OdometerData:
    """Odometer speeds at the truth samples nearest to every 1/rate_hz [s] (after the first).

    scale_factor : k [-] (e.g. 0.01 = reads 1 % high); sigma_m_s : white-noise σ [m/s] (also the
    ``std`` column). Returns :class:`aidnav.io.aux_sensors.OdometerData`.
    """
    dt = float(np.median(np.diff(truth.time)))
    step = max(1, int(round(1.0 / (rate_hz * dt))))
    idx = np.arange(step, len(truth.time), step)
    q = euler_to_quat_batch(np.ascontiguousarray(truth.rph[idx]))
    Cbv = dcm_from_euler(*mounting_rph_rad)
    v_y = np.empty(len(idx))
    for j, i in enumerate(idx):
        vb = dcm_from_quat(q[j]).T @ truth.vel[i]
        if lever_b is not None:
            if omega_nb_b is None:
                raise ValueError("a lever arm needs omega_nb_b (body rate w.r.t. n at the truth samples)")
            vb = vb + np.cross(omega_nb_b[i], lever_b)
        v_y[j] = (Cbv @ vb)[1]
    speed = (1.0 + scale_factor) * v_y + sigma_m_s * rng.standard_normal(len(idx))
    return OdometerData(truth.time[idx].copy(), speed, np.full(len(idx), float(sigma_m_s)))
