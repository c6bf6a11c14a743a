"""State layouts by name: the one place that says which index holds which error state.

Strapdown (nominal) state ``st`` (10,): ``ST_POS`` lat, lon [rad], h [m]; ``ST_VEL`` v^n ENU [m/s];
``ST_Q`` q_b^n (4). Error state (computed − true for the navigation block, true − estimated for the
sensor and calibration residuals, see :mod:`aidnav.filters.ins_errors`):

========  =========================================  ======================
block     content                                    layouts
========  =========================================  ======================
PHI  0:3  misalignment φ [rad]                        all
DV   3:6  δv^n [m/s]                                  all
DP   6:9  δL, δλ [rad], δh [m]                        all
BG  9:12  gyro bias residual [rad/s]                  15, 17, 21, 24, 27, 33
BA 12:15  accel bias residual [m/s²]                  15, 17, 21, 24, 27, 33
SG 15:18  gyro scale-factor residual [-]              21, 24, 27, 33
SA 18:21  accel scale-factor residual [-]             21, 24, 27, 33
MG 21:27  gyro misalignment residual [rad]            27, 33
MA 27:33  accel misalignment residual [rad]           33
CLK       receiver clock bias [m], drift [m/s]        17 (15:17), 11 (9:11)
ISB       inter-system biases [m] (tight: one per     after CLK (before RERR)
          non-GPS system, that system's receiver
          clock − the GPS clock)
TDCP      clone of the previous epoch's antenna       after ISB (before RERR) with the carrier
          position ECEF [m] (3) and clock bias [m]   phase (tight: time-differenced phase rows)
RERR      per-satellite range errors [-] (tight)      after CLK (and ISB) when switched on
AUX       calibration states (odometer scale factor   after the INS block
          [-], barometer bias [m], GNSS lever arm
          [m], time offset [s], mounting ρ [rad],
          flexure θ [rad] (and θ̇ [rad/s]))
========  =========================================  ======================

The named layouts: 15 = navigation + biases; 17 = 15 + receiver clock (tight); 21 = 15 + scale
factors; 27 = 21 + gyro misalignment (6, ``ins_errors.MIS_OUT``/``MIS_IN``); 33 = 27 + accelerometer
misalignment (6, the same order); 24 = 21 + 3 calibration states (e.g. a lever arm). :func:`make_layout`
builds the index table of any INS block plus calibration states; kernels read indices from it (``L_*``
entries), never literal slices.
"""

from __future__ import annotations

import numpy as np

from .ins_errors import BA, BG, DP, DV, MA, MG, N_ST, PHI, SA, SG, ST_POS, ST_Q, ST_VEL

MIS_PAIRS = ("xy", "xz", "yx", "yz", "zx", "zy")  # misalignment m_(out)(in), the MG and MA blocks' order

# error-state blocks of the INS model (ins_errors)
NAV = 9  # φ, δv, δp
__all__ = ["PHI", "DV", "DP", "BG", "BA", "SG", "SA", "MG", "MA", "ST_POS", "ST_VEL", "ST_Q", "N_ST", "NAV",
           "AUX_NAMES", "RN_VEL", "RN_POS", "RN_SVEL", "RN_SPOS", "RN_ACC", "RN_LEVER", "N_RN", "L_RERR",
           "L_ISB", "L_TDCP", "L_TOFF", "L_MOUNT", "L_VDEL", "L_GPE", "L_FLEX", "make_layout", "layout_names",
           "LAYOUTS"]

# the course fix of a re-initialisation event (engine ``Init.reset_nav``, N_RN,): its velocity ENU [m/s],
# position lat, lon [rad], h [m], velocity σ ENU [m/s], position σ E, N, U [m], the vehicle's acceleration
# ENU at the fix from the GNSS velocities [m/s²] (0 where unknown), antenna lever arm (body) [m]
RN_VEL, RN_POS, RN_SVEL, RN_SPOS, RN_ACC, RN_LEVER, N_RN = 0, 3, 6, 9, 12, 15, 18

# calibration (auxiliary) states the engine knows: name -> width
AUX_NAMES = {"odometer_scale": 1, "baro_bias": 1, "clock": 2, "lever_arm": 3, "time_offset": 1, "mounting": 3,
             "velocity_delay": 1, "gnss_pos_error": 3, "flexure": 6, "flexure_angle": 3}

# entries of the int64 layout table (kernels read these)
L_N = 0  # total number of error states
L_NINS = 1  # size of the INS block (15, 21, 27 or 33: ins_errors.fill_model)
L_ODO = 2  # index of the odometer scale-factor residual, -1: none
L_BARO = 3  # index of the barometer bias residual, -1: none
L_CLK = 4  # index of the clock bias (drift at +1), -1: none
L_LEVER = 5  # index of a 3-state lever-arm calibration, -1: none
L_TOFF = 6  # index of the IMU-GNSS time-offset residual [s] (added to the IMU stamps), -1: none
L_MOUNT = 7  # index of the 3-state mounting residual ρ [rad] (vehicle frame), -1: none
L_VDEL = 8  # index of the GNSS velocity delay residual [s] (velocity older than its stamp), -1: none
L_GPE = 9  # index of the 3 Gauss-Markov GNSS position-error states ENU [m] (time-correlated), -1: none
L_FLEX = 10  # index of the flexure angle θ (3) [rad] (θ̇ (3) [rad/s] at +3 for "flexure"), -1: none
L_RERR = 11  # index of the per-satellite range-error states (tight coupling: one per satellite column of
# an epoch record, normalised: unit-variance Gauss-Markov, range error = σ_j(E) × state), -1: none
L_ISB = 12  # index of the inter-system bias states [m] (tight coupling: one per non-GPS system of the
# log, in the order of the epoch rows' system slots; that system's receiver clock − the GPS one), -1: none
L_TDCP = 13  # index of the time-differenced carrier phase's clone (tight coupling): the antenna position at
# the previous GNSS epoch, ECEF [m] (3), and that epoch's receiver clock bias [m] (1), true − estimated;
# -1: none
L_SIZE = 14

LAYOUTS = {15: dict(scale_factors=False), 17: dict(scale_factors=False, aux=("clock",)),
           21: dict(scale_factors=True), 24: dict(scale_factors=True, aux=("lever_arm",)),
           27: dict(scale_factors=True, misalignment=True),
           33: dict(scale_factors=True, misalignment=True, accel_misalignment=True)}


def make_layout(scale_factors: bool = False, aux: tuple[str, ...] = (), misalignment: bool = False,
                accel_misalignment: bool = False) -> np.ndarray:
    """Index table (int64, ``L_*`` entries) of the INS block (15, 21, with the gyro ``misalignment`` 27,
    with the ``accel_misalignment`` too 33 states) plus calibration states ``aux`` (names of
    :data:`AUX_NAMES`, appended in the given order)."""
    lay = np.full(L_SIZE, -1, np.int64)
    n = 33 if accel_misalignment else (27 if misalignment else (21 if scale_factors else 15))
    lay[L_NINS] = n
    slot = {"odometer_scale": L_ODO, "baro_bias": L_BARO, "clock": L_CLK, "lever_arm": L_LEVER,
            "time_offset": L_TOFF, "mounting": L_MOUNT, "velocity_delay": L_VDEL, "gnss_pos_error": L_GPE,
            "flexure": L_FLEX, "flexure_angle": L_FLEX}
    for name in aux:
        if name not in AUX_NAMES:
            raise ValueError(f"unknown calibration state {name!r}; known: {sorted(AUX_NAMES)}")
        if lay[slot[name]] >= 0:
            raise ValueError(f"calibration state {name!r} given twice")
        lay[slot[name]] = n
        n += AUX_NAMES[name]
    lay[L_N] = n
    return lay


def _width(lay: np.ndarray, slot: int) -> int:
    """Number of states of the block at ``lay[slot]`` (up to the next block or the end)."""
    after = [int(lay[s]) for s in range(L_ODO, L_SIZE) if lay[s] > lay[slot]]
    return min(after + [int(lay[L_N])]) - int(lay[slot])


def layout_names(lay: np.ndarray) -> list[str]:
    """One name per error state of layout ``lay`` (for tables and data frames)."""
    names = [f"{b}_{a}" for b in ("phi", "dv") for a in "enu"] + ["dlat", "dlon", "dh"]
    blocks = ["gyro_bias", "accel_bias"] + (["gyro_sf", "accel_sf"] if lay[L_NINS] >= 21 else [])
    names += [f"{b}_{a}" for b in blocks for a in "xyz"]
    n_mis = max(int(lay[L_NINS]) - 21, 0) // 6  # misalignment triads: gyro (27), then accelerometer (33)
    for tri in ("gyro", "accel")[:n_mis]:
        names += [f"{tri}_mis_{MIS_PAIRS[k]}" for k in range(6)]
    aux = sorted((int(lay[s]), nm) for s, nm in ((L_ODO, "odometer_scale"), (L_BARO, "baro_bias"),
                                                  (L_CLK, "clock"), (L_LEVER, "lever_arm"),
                                                  (L_TOFF, "time_offset"), (L_MOUNT, "mounting"),
                                                  (L_VDEL, "velocity_delay"), (L_GPE, "gnss_pos_error"),
                                                  (L_FLEX, "flexure_angle" if _width(lay, L_FLEX) == 3 else
                                                   "flexure"))
                 if lay[s] >= 0)
    for _, nm in aux:
        names += ([nm] if AUX_NAMES[nm] == 1 else
                  (["clock_bias", "clock_drift"] if nm == "clock" else [f"{nm}_{a}" for a in "xyz"]))
        names += [f"flexure_rate_{a}" for a in "xyz"] if nm == "flexure" else []
    return names
