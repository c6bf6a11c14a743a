"""Barometric height with a bias state."""

from __future__ import annotations

from aidnav.jit import njit

from ..layout import DP, L_BARO, NAV


@njit(cache=True)
def baro_model(nav, row, par, lay, H, z, R):
    """Barometric height h_b = h + b (b: the barometer's bias, slowly varying).

    row = [h_b [m], σ [m]]; state ``lay[L_BARO]`` = b − b̂ (residual, fed back b̂ += r̂), b̂ from
    ``nav.bias``. z = (ĥ + b̂) − h_b ≈ δh − r: H[δh] = 1, H[r] = −1.
    """
    b = nav.bias[lay[L_BARO] - NAV] if lay[L_BARO] >= 0 else 0.0
    H[0, :] = 0.0
    H[0, DP + 2] = 1.0
    if lay[L_BARO] >= 0:
        H[0, lay[L_BARO]] = -1.0
    z[0] = nav.st[2] + b - row[0]
    R[0, 0] = row[1] ** 2
    return 1
