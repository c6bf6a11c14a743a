"""The held-heading repair's kernels (issue 35, p35h): the tilt and accelerometer-bias corrections summed
while the initial heading is held and the vehicle moves, and their covariance added at the alignment."""

import numpy as np

from aidnav.filters.held_heading import G_BA, G_TILT, N_GAP, note_held_correction, repair_held_tilt
from aidnav.filters.ins_errors import turn_tilt_by
from aidnav.filters.layout import BA, PHI

IX = np.arange(15, dtype=np.int64)  # the full 15-state layout, no subset


def _dx(tilt_en, ba):
    dx = np.zeros(15)
    dx[PHI:PHI + 2] = tilt_en
    dx[BA:BA + 3] = ba
    return dx


def test_a_correction_repaired_at_the_heading_it_was_made_adds_its_outer_product():
    gap = np.zeros(N_GAP)
    note_held_correction(_dx([1e-3, -2e-3], [0.01, -0.02, 0.005]), 0.7, gap)
    P = np.eye(15) * 1e-6
    repair_held_tilt(P, gap, 0.7, IX)
    d = np.array([1e-3, -2e-3, 0.01, -0.02, 0.005])
    rows = [PHI, PHI + 1, BA, BA + 1, BA + 2]
    np.testing.assert_allclose(P[np.ix_(rows, rows)], np.eye(5) * 1e-6 + np.outer(d, d), atol=1e-15)
    others = [i for i in range(15) if i not in rows]
    np.testing.assert_array_equal(P[np.ix_(others, others)], np.eye(len(others)) * 1e-6)
    np.testing.assert_array_equal(gap[G_TILT:], 0.0)  # the sums are cleared


def test_the_tilt_turns_with_the_heading_as_the_covariance_turn_does():
    """Noted at heading h0, repaired at h0 + dh: the tilt part equals the outer product at h0 turned by
    ``ins_errors.turn_tilt_by`` (the engine's tilt turn) by dh — the tilt belongs to the body."""
    h0, dh = 0.4, np.radians(130.0)
    t = np.array([2e-3, 1e-3])
    gap = np.zeros(N_GAP)
    note_held_correction(_dx(t, [0.0, 0.0, 0.0]), h0, gap)
    P = np.zeros((15, 15))
    repair_held_tilt(P, gap, h0 + dh, IX)
    Q = np.zeros((15, 15))
    Q[:2, :2] = np.outer(t, t)
    turn_tilt_by(Q, PHI, PHI + 1, dh)
    np.testing.assert_allclose(P[:2, :2], Q[:2, :2], atol=1e-15)
    assert abs(np.trace(P[:2, :2]) - t @ t) < 1e-15  # a rotation: the size is kept


def _turned(v, dh):
    """The tilt vector ``v`` turned by the engine's tilt turn for a heading change dh (its row pass on a
    column that holds v)."""
    Q = np.zeros((15, 15))
    Q[PHI:PHI + 2, 5] = v
    turn_tilt_by(Q, PHI, PHI + 1, dh)
    return Q[PHI:PHI + 2, 5].copy()


def test_the_same_body_tilt_at_two_headings_adds_up():
    """One body-frame tilt correction made at two nodes whose computed headings differ by 90°: in the
    navigation frame the two vectors are perpendicular, in the body's axes they add (2× the tilt)."""
    gap = np.zeros(N_GAP)
    tb = np.array([1e-3, 0.5e-3])  # at heading 0
    for h in (0.3, 0.3 + np.pi / 2):
        note_held_correction(_dx(_turned(tb, h), [0.0, 0.0, 1e-3]), h, gap)
    np.testing.assert_allclose(gap[G_TILT:G_TILT + 2], 2 * tb, rtol=1e-12)
    np.testing.assert_allclose(gap[G_BA:G_BA + 3], [0.0, 0.0, 2e-3])
