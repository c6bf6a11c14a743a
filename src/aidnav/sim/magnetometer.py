"""Magnetometer heading simulation: ψ_m = ψ + b + white noise (b: a constant residual of the
compensation, e.g. an uncorrected hard-iron or declination error)."""

from __future__ import annotations

import numpy as np

from aidnav.io.aux_sensors import HeadingData


def simulate_mag_heading(truth, rate_hz: float, sigma_deg: float, rng: np.random.Generator,
                         bias_deg: float = 0.0) -> HeadingData:
    """True headings of the IMU's forward axis at the truth samples nearest to every 1/rate_hz [s] (after
    the first), plus ``bias_deg`` and white noise of σ ``sigma_deg`` (also the ``std`` column), in
    radians wrapped to [0, 2π). Returns :class:`aidnav.io.aux_sensors.HeadingData`."""
    dt = float(np.median(np.diff(truth.time)))
    step = max(1, int(round(1.0 / (rate_hz * dt))))
    idx = np.arange(step, len(truth.time), step)
    sig = np.radians(sigma_deg)
    psi = truth.rph[idx, 2] + np.radians(bias_deg) + sig * rng.standard_normal(len(idx))
    return HeadingData(truth.time[idx].copy(), psi % (2 * np.pi), np.full(len(idx), sig))
