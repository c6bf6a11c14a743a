"""Barometric height simulation: h_b = h + b(t) + white noise, b(t) = b0 + random walk."""

from __future__ import annotations

import numpy as np

from aidnav.io.aux_sensors import BaroData


def simulate_baro(truth, rate_hz: float, bias_m: float, sigma_m: float, rng: np.random.Generator,
                  bias_rw_m_sqrt_s: float = 0.0) -> BaroData:
    """Barometric heights at the truth samples nearest to every 1/rate_hz [s] (after the first).

    bias_m : b0 [m]; sigma_m : white-noise σ [m] (also the ``std`` column); bias_rw_m_sqrt_s : random
    walk of the bias [m/√s]. Returns :class:`aidnav.io.aux_sensors.BaroData`.
    """
    dt = float(np.median(np.diff(truth.time)))
    step = max(1, int(round(1.0 / (rate_hz * dt))))
    idx = np.arange(step, len(truth.time), step)
    t = truth.time[idx]
    gaps = np.diff(np.concatenate([[truth.time[0]], t]))
    db = bias_rw_m_sqrt_s * np.sqrt(gaps) * rng.standard_normal(len(t))
    bias = bias_m + np.cumsum(db)
    h = truth.height[idx] + bias + sigma_m * rng.standard_normal(len(t))
    return BaroData(t.copy(), h, np.full(len(t), float(sigma_m)))
