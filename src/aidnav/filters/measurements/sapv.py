"""Satellite-antenna pointing vector (SAPV) angles of a GEO satellite (seed 000, §1.1)."""

from __future__ import annotations

import numpy as np

from aidnav.jit import njit
from aidnav.models.sapv import OK
from aidnav.nav.geo_pointing import az_el_from_body, az_el_jacobians, beam_body

from ..layout import DP, PHI


@njit(cache=True)
def sapv_angles(st, Cbn, sat_ecef, az_meas, el_meas, use_position, H, z):
    """Satellite-antenna pointing vector (seed 000, §1.1 eq. 29): antenna azimuth and elevation.

    st : strapdown state (lat, lon [rad], h [m], v, q); Cbn : its C_b^n; sat_ecef : GEO satellite ECEF [m];
    az_meas, el_meas : the antenna's axis angles [rad] (az clockwise from body forward, el above the body
    x-y plane, :func:`aidnav.nav.geo_pointing.az_el_from_body`).
    z = [wrap(az_computed − az_meas) to (−π, π], el_computed − el_meas] [rad] ≈ H δx, with the exact
    Jacobians of :func:`aidnav.nav.geo_pointing.az_el_jacobians` at the computed state:
    H = [−A C_n^b [r_n×], 0, A C_n^b (C_e^n B + [r_n×] D) (only if ``use_position``), 0] (§1.1 eq. 23;
    the seed drops the position columns, eq. 26). Fills H (2×n) and z (2,).
    """
    az, el, H_phi, H_pos = az_el_jacobians(st[0], st[1], st[2], Cbn, sat_ecef)
    H[:, :] = 0.0
    d = az - az_meas
    d = d - 2.0 * np.pi * np.floor((d + np.pi) / (2.0 * np.pi))
    if d == -np.pi:
        d = np.pi
    z[0] = d
    z[1] = el - el_meas
    for i in range(2):
        for j in range(3):
            H[i, PHI + j] = H_phi[i, j]
            if use_position:
                H[i, DP + j] = H_pos[i, j]


@njit(cache=True)
def sapv_model(nav, row, par, lay, H, z, R):
    """Uniform form of :func:`sapv_angles`: row = [satellite ECEF (3) [m], az, el, σ_az, σ_el [rad]];
    par[0] > 0: use the position columns."""
    sapv_angles(nav.st, nav.C, row[0:3].copy(), row[3], row[4], par[0] > 0, H[:2], z[:2])
    R[0, 0], R[0, 1], R[1, 0], R[1, 1] = row[5] ** 2, 0.0, 0.0, row[6] ** 2
    return 2


# codes of the per-epoch SAPV status (the engine log's status: 1 used, 0 gated out, below −1 skipped)
SAPV_UNUSED = -1  #: antenna not tracking (reason flag), or SAPV not used in this run
SAPV_BAD_INPUT = -2  #: NaN on an epoch flagged as tracking, or an angle outside its range
SAPV_BELOW_HORIZON = -3  #: the satellite is below the local horizon at the INS position
#: why SAPV epochs were skipped (keys of the federated filter's counts["sapv_skipped"])
SAPV_SKIP_REASONS = {
    "not_tracking": "antenna reports no lock (SapvData.reason != OK)",
    "nan": "non-finite az/el on an epoch flagged as tracking",
    "angle_out_of_range": "azimuth outside [0, 2*pi) or elevation outside [-pi/2, pi/2] rad",
    "below_horizon": "the satellite is below the local horizon at the INS position",
}


@njit(cache=True)
def carry_angles(row, w_ib_b, dt_back):
    """The angles of a SAPV row (``sapv_model`` layout) describe the body at t_j = t_k − dt_back: carry
    the (nav-fixed) line of sight into the body at t_k, r_b(k) = (I − [θ×]) r_b(j), θ = ω_ib^b dt_back."""
    if dt_back > 1e-9:
        u = beam_body(row[3], row[4])
        row[3], row[4] = az_el_from_body(u - np.cross(w_ib_b * dt_back, u))


def sapv_input_check(sapv) -> np.ndarray:
    """(S,) str: why each SAPV epoch cannot be used (a key of :data:`SAPV_SKIP_REASONS`), "" if it can.

    The angles follow :func:`aidnav.nav.geo_pointing.az_el_from_body`: az ∈ [0, 2π), el ∈ [−π/2, π/2]
    [rad]; anything else is a unit or convention error in the data (e.g. degrees), not a measurement.
    """
    az, el = np.asarray(sapv.az, float), np.asarray(sapv.el, float)
    out = np.full(len(az), "", "<U20")
    finite = np.isfinite(az) & np.isfinite(el)
    with np.errstate(invalid="ignore"):
        bad_range = finite & ((az < 0.0) | (az >= 2.0 * np.pi) | (np.abs(el) > 0.5 * np.pi))
    tracking = np.asarray(sapv.reason) == OK
    out[tracking & bad_range] = "angle_out_of_range"
    out[tracking & ~finite] = "nan"
    out[~tracking] = "not_tracking"
    return out


def sapv_rows(sapv) -> np.ndarray:
    """(S, 7) ``sapv_model`` rows of :class:`aidnav.sim.sapv.SapvData`: satellite ECEF, az, el, σ_az, σ_el."""
    k = len(sapv)
    return np.ascontiguousarray(np.column_stack([np.tile(np.asarray(sapv.sat_ecef, float), (k, 1)), sapv.az,
                                                 sapv.el, np.tile(np.asarray(sapv.sigma, float), (k, 1))]))


def sapv_counts(status: np.ndarray, skip: np.ndarray, used: bool) -> dict:
    """Marks bad input (−2) in the per-epoch ``status`` (in place) and counts used / gated / skipped
    epochs by reason (:data:`SAPV_SKIP_REASONS`; none counted as skipped when SAPV is not ``used``)."""
    skipped = dict.fromkeys(SAPV_SKIP_REASONS, 0)
    if used:
        status[(skip == "nan") | (skip == "angle_out_of_range")] = SAPV_BAD_INPUT
        for k in ("not_tracking", "nan", "angle_out_of_range"):
            skipped[k] = int(np.count_nonzero(skip == k))
        skipped["below_horizon"] = int(np.count_nonzero(status == SAPV_BELOW_HORIZON))
    return {"sapv_used": int(np.count_nonzero(status == 1)), "sapv_gated": int(np.count_nonzero(status == 0)),
            "sapv_skipped": skipped}
