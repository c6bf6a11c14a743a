"""Shared pieces of the measurement models: the uniform signature and small helpers (numba).

**Uniform signature** of every model (what :func:`aidnav.filters.engine.run_filter` calls):

    ``m = model(nav, row, par, lay, H, z, R)``

* ``nav`` :class:`Nav` — the INS at the update node: ``st`` (10,) strapdown state (lat, lon [rad],
  h [m], v^n [m/s], q_b^n), ``C`` its C_b^n, ``w`` (4, 3) rates [rad/s]: ``W_IB`` mean ω_ib^b of the
  interval, ``W_FIX`` ω_ib^b of the last sample, ``W_IE`` ω_ie^n, ``W_IN`` ω_in^n; ``dt_back`` [s]:
  node time − measurement time (the INS is moved back along its velocity where a model needs it);
  ``bias`` (n − 9,): the current sensor-error and calibration estimates (index = state index − 9).
* ``row`` (W,) float: the measurement record (values and their σ; layout documented per model).
* ``par`` (P,) float: the model's constant parameters (lever arms, mounting, σ of constraints).
* ``lay`` (``layout.L_SIZE``,) int: the state layout (:mod:`aidnav.filters.layout`).
* ``H`` (≥m, n), ``z`` (≥m,), ``R`` (≥m, ≥m): filled in their first m rows (R zero off-diagonal).
* returns m, the number of rows (0: nothing to update: not measured, below a speed threshold, …).

Innovations are z = (value predicted from the INS) − (measured value) ≈ H δx, δx in the layout's
convention (navigation errors computed − true, calibration residuals true − estimated).
"""

from __future__ import annotations

from collections import namedtuple

from aidnav.jit import njit
from aidnav.nav.rotations import cross, skew  # noqa: F401  (re-exported: the models import them from here)

Nav = namedtuple("Nav", ["st", "C", "w", "dt_back", "bias"])
W_IB, W_FIX, W_IE, W_IN = 0, 1, 2, 3
MAX_ROWS = 6  # rows of the largest model (velocity + attitude matching): the engine's work arrays


@njit(cache=True, inline="always")
def skew_into(H, r0, c0, a, sign):
    """H[r0:r0+3, c0:c0+3] += sign·[a×]."""
    H[r0 + 0, c0 + 1] += -sign * a[2]
    H[r0 + 0, c0 + 2] += sign * a[1]
    H[r0 + 1, c0 + 0] += sign * a[2]
    H[r0 + 1, c0 + 2] += -sign * a[0]
    H[r0 + 2, c0 + 0] += -sign * a[1]
    H[r0 + 2, c0 + 1] += sign * a[0]


@njit(cache=True)
def diag_r(R, m, sig):
    """R[:m, :m] = diag(sig[:m]²), zero elsewhere in those rows."""
    for i in range(m):
        for j in range(m):
            R[i, j] = 0.0
        R[i, i] = sig[i] * sig[i]
