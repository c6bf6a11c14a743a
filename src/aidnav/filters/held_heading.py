"""The engine's kernels for a heading held unknown while the vehicle moves (:mod:`.engine`; issue 35).

Before the first course alignment (``Init.reset_idx``) the heading is held unknown (σ up to 180°, no
correlation). Once the vehicle moves, the strapdown integrates the acceleration along that heading, which
is off by anything up to 180°: the velocity fixes see a horizontal acceleration error that the linear
model, the held heading having no correlation, puts into the tilt and the accelerometer bias (issue 35,
session 12, n35c finding 3: roll/pitch −0.23/−0.37° → −0.56/−0.96° in 0.9 s, a 14-mg bias learnt
against a true 2.3 mg). The course alignment resets heading, velocity and position and repairs the time
states (:func:`.engine._reinit`), but the tilt and the bias keep what the meaningless velocity put into
them, with the covariance of an update that had information. :func:`note_held_correction` sums those
corrections (the tilt in the body's horizontal axes: it belongs to roll and pitch, and the computed
heading moves by tens of degrees per node while held) and :func:`repair_held_tilt` adds their outer
product to the tilt and accelerometer-bias block at the alignment: the estimates are kept (a
calibration is repaired, never thrown away: issue 35, item 5) and the covariance says that what the held
period moved them by may be wrong, so the fixes after the alignment, with a meaningful heading, can move
them back.

``gap`` is the engine's carried array (:class:`.engine.Carry`); its entries from :data:`G_TILT` on are
this module's: the tilt corrections (2, at heading 0) and the accelerometer-bias corrections (3) fed back
at moving nodes while the initial heading is held.
"""

from __future__ import annotations

import numpy as np

from aidnav.jit import njit
from aidnav.nav.rotations import dcm_from_quat

from .ins_errors import turn_tilt_by
from .layout import BA, PHI, ST_Q

__all__ = ["G_BA", "G_TILT", "N_GAP", "note_held_correction", "repair_held_tilt", "turn_held_heading"]

G_TILT, G_BA = 6, 8  # in the carried gap array: tilt corrections E, N (at heading 0); accel bias x, y, z
N_GAP = 11  # the carried gap array's length (engine: 6 entries of its own)


@njit(cache=True)
def turn_held_heading(st, P, h0, held, ix):
    """A heading held unknown (``held``: before the first course alignment or after an IMU gap) that a
    node's updates moved (from ``h0`` [rad] to the strapdown's heading now) turns the tilt error and its
    covariance with it, as a course alignment does (:func:`.ins_errors.set_heading`): the tilt belongs to
    the body's roll and pitch, so in the navigation frame it turns with the heading (issue 35, k35t)."""
    if held and ix[PHI] >= 0 and ix[PHI + 1] >= 0:
        C = dcm_from_quat(st[ST_Q:ST_Q + 4])
        turn_tilt_by(P, ix[PHI], ix[PHI + 1], np.arctan2(C[0, 1], C[1, 1]) - h0)


@njit(cache=True)
def note_held_correction(dx, h0, gap):
    """Add a moving node's feedback ``dx`` (full INS layout) while the initial heading is held to the sums
    in ``gap``: the tilt correction φ̂_E, φ̂_N, made at the computed heading ``h0`` [rad], turned to heading
    0 (the rotation about Up by h0: :func:`.ins_errors.turn_tilt_by`'s convention), and the accelerometer
    bias correction (body axes) where the layout has one."""
    c, s = np.cos(h0), np.sin(h0)
    gap[G_TILT] += c * dx[PHI] - s * dx[PHI + 1]
    gap[G_TILT + 1] += s * dx[PHI] + c * dx[PHI + 1]
    if dx.shape[0] >= BA + 3:
        for i in range(3):
            gap[G_BA + i] += dx[BA + i]


@njit(cache=True)
def repair_held_tilt(P, gap, heading, ix):
    """At the course alignment that ends the initial hold (the computed heading now ``heading`` [rad]):
    the tilt and accelerometer-bias corrections summed by :func:`note_held_correction`, d (tilt turned
    to ``heading``, bias), are added to their block of ``P`` as d dᵀ — the error the held period may have
    put in, along the direction it moved them — and the sums are cleared. ``ix``: index in P of each
    state of the full INS layout (−1: not in the filter)."""
    c, s = np.cos(-heading), np.sin(-heading)
    d = np.zeros(5)
    d[0] = c * gap[G_TILT] - s * gap[G_TILT + 1]
    d[1] = s * gap[G_TILT] + c * gap[G_TILT + 1]
    for i in range(3):
        d[2 + i] = gap[G_BA + i]
    rows = np.array([ix[PHI], ix[PHI + 1], ix[BA], ix[BA + 1], ix[BA + 2]])  # (ix: ≥ 15 entries)
    for a in range(5):
        for b in range(5):
            if rows[a] >= 0 and rows[b] >= 0:
                P[rows[a], rows[b]] += d[a] * d[b]
    for i in range(G_TILT, N_GAP):
        gap[i] = 0.0
