"""The states a fix cannot inform while the heading is held unknown (:mod:`.engine`; issue 35).

Before the first course alignment (``Init.reset_idx``) and after an IMU gap until a GNSS course re-aligns
it, the heading is held unknown (σ up to 180°, no correlation): every Jacobian whose horizontal direction
is the computed heading's is then unknown, and a linearised update would read the heading's error, or its
wander, as information on the states behind those Jacobians. :func:`consider_states` keeps them out of the
update (a Schmidt "consider" update); :func:`considered_states` names them.
"""

from __future__ import annotations

import numpy as np

from aidnav.jit import njit
from aidnav.nav.earth import radii
from aidnav.nav.rotations import dcm_from_quat

from .layout import DP, L_LEVER, L_TOFF, L_VDEL, ST_POS, ST_Q

__all__ = ["consider_states", "considered_states", "reset_lever"]


@njit(cache=True)
def considered_states(lay, nsub):
    """Indices in P of the time offset, the velocity delay and the GNSS lever arm (3) of the layout table
    ``lay`` — −1 where not estimated, and all −1 with a state subset (``nsub`` > 0): the states
    :func:`consider_states` considers while the heading is held."""
    il = lay[L_LEVER]
    if nsub:
        return (-1, -1, -1, -1, -1)
    return (lay[L_TOFF], lay[L_VDEL], il, il + 1 if il >= 0 else -1, il + 2 if il >= 0 else -1)


@njit(cache=True)
def consider_states(H, R, m, P, tc):
    """A fix read while the heading is held unknown (before the first course alignment, after an IMU gap)
    does not update the time offset, velocity delay and GNSS lever arm (indices ``tc``; −1: not
    estimated): their columns of ``H`` (m rows) are the INS's v^n and a^n, and C_b^n l (C_b^n [ω×] l),
    whose horizontal direction is the held heading's, i.e. unknown. A heading error ψ puts an innovation
    of up to 2|v| (|a|·Δt) along any direction, and near ψ = 180° along v (a) itself, which the linear
    model can only read as a time offset (issue 35, m35u's no-``vu`` run: 0.43 s learnt from one velocity
    fix at the start of motion with the heading 156° off); and a held heading that wanders at rest by tens
    of degrees per node turns C_b^n l with it while the antenna stands still, which the model reads as
    lever-arm information (issue 35, p35h: the lever σ 0.29 → 0.10 m over the start's rest, correlated
    with the tilt and accelerometer bias; at the first fixes after the course alignment that fake
    information separated the tilt from the bias, tilt σ 0.6° → 0.2° in one update against a 1.1° error).
    So they are *considered*, not estimated: their correlations with the other states are zeroed (their
    own block kept, as the held heading's are) and their part of the innovation, H_T P_TT H_Tᵀ, goes into
    R, so the update is honest about them and leaves them as they are."""
    for a in tc:
        if a < 0:
            continue
        for j in range(P.shape[0]):
            inside = False
            for b in tc:
                inside = inside or j == b
            if not inside:
                P[a, j], P[j, a] = 0.0, 0.0
    for i in range(m):
        for j in range(m):
            for a in tc:
                for b in tc:
                    if a >= 0 and b >= 0:
                        R[i, j] += H[i, a] * P[a, b] * H[j, b]
    for a in tc:
        if a >= 0:
            for i in range(m):
                H[i, a] = 0.0


@njit(cache=True)
def reset_lever(st, P, ix, il):
    """The GNSS lever arm's unknown part in a course re-initialisation's position (:func:`.engine._reinit`:
    the INS position taken from the fix as antenna − C_b^n l̂, δp set to the fix's σ, uncorrelated). The
    IMU's position is then off by the fix's error plus C_b^n r_l (r_l = true − estimated lever, index
    ``il`` in P, −1: not estimated; :func:`.measurements.gnss.gnss_position_model`: H_l = −C_b^n), so
    δp = ε_p + C_b^n r_l, P ← J P Jᵀ: the position fixes after the reset see what they saw before it, the
    lever arm and the position error one sum, not two independent errors whose split the next fixes
    would "learn" (issue 35, p35h: with the lever arm estimated, the first fixes after a held start's
    course alignment took the tilt σ from ≈ 0.6° to 0.2° against errors of 1–1.7°; the velocity's
    C_b^n [ω×] r_l, at the start of motion, is left out). ``ix``: index in P of each INS state."""
    if il < 0:
        return
    C = dcm_from_quat(st[ST_Q:ST_Q + 4])
    rm, rn = radii(st[ST_POS])
    h = st[ST_POS + 2]
    sc = np.array([1.0 / ((rn + h) * np.cos(st[ST_POS])), 1.0 / (rm + h), 1.0])  # E, N, U metres → δλ, δL, δh
    n = P.shape[0]
    J = np.eye(n)
    for i in range(3):  # δp rows: δL (north), δλ (east), δh
        jp = ix[DP + i]
        k = 1 if i == 0 else (0 if i == 1 else 2)
        if jp >= 0:
            for j in range(3):
                J[jp, il + j] = C[k, j] * sc[k]
    P[:, :] = J @ P @ J.T
