"""The tilt's turn with the feedback's heading correction (:func:`turn_with_feedback`), and what the engine
keeps of a node for the RTS pass (:func:`aidnav.filters.smoother.rts`) with the node's tilt turns as part of
its transition (:func:`keep_prior`, :func:`keep_post`; issue 35, session 13).

**The turn.** The tilt error belongs to the body's roll and pitch, so in the navigation frame it turns with
every rotation about Up applied to the computed frame: the exact composition of a heading correction with
the tilt (R_err = R_U(ψ) R_tilt: a correction R_U(ψ̂) leaves R_U(ψ − ψ̂) R_U(ψ̂) R_tilt R_U(−ψ̂), the tilt
turned by ψ̂), which the first-order model drops as second order and which matters once the correction is
tens of degrees (the heading after a long stop; a course alignment, :func:`.ins_errors.set_heading`). It is
made at every moving node: for one small correction it is of the order of the terms the model drops, but a
heading that comes back in many small corrections would otherwise leave the tilt's frame off by their sum
(session 12 kept it to single corrections above 5°, because the RTS pass and the batched engine did not see
it: the parked cells then failed on roll; with a threshold on the corrections' sum the ship preset's did).

**The RTS pass.**
The RTS pass takes at each node k the prior P⁻_k and the Φ_k that made it (kept before the updates), the
update dx_k and the posterior P⁺_k (kept after the feedback), and assumes one linear model of one error
state: e⁻_k = Φ_k e⁺_{k−1} + w, e⁺_k = e⁻_k − dx_k. The engine also turns the tilt rows of P with a heading
change of the computed frame (:func:`.ins_errors.turn_tilt_by`; the tilt belongs to the body's roll and
pitch): at a static node, before the updates, with the heading's change since the last node
(``engine._turn_tilt_at_rest``), and after the feedback with the heading correction it made
(:func:`turn_with_feedback`). A turn T is a change of the error state's coordinates, e ← T e, and P ← T P Tᵀ:
unless the kept matrices say so, the pass mixes the coordinates before and after it (``Ps_k − P⁻_k`` of
two frames: the smoothed P then exceeds the forward P).

* The turn at rest is made after the prediction: P⁻_k = T (Φ_k P⁺_{k−1} Φ_kᵀ + Q) Tᵀ, so the transition
  is T Φ_k (:func:`keep_prior` keeps T Φ_k beside the turned P⁻_k).
* The turn after the feedback gives P⁺_k = T P_k Tᵀ in the turned coordinates; the prior and the update are
  written in them too (:func:`keep_post`: P⁻_k ← T P⁻_k Tᵀ, Φ_k ← T Φ_k, dx_k ← T dx_k). With these the
  pass's gain is A = P⁺ (TΦ)ᵀ (T P⁻ Tᵀ)⁻¹ = P⁺ Φᵀ P⁻⁻¹ Tᵀ and it computes exactly
  ds_{k−1} = A₀ (dx_k + Tᵀ ds_k), Ps_{k−1} = P⁺ + A₀ (Tᵀ Ps_k T − P⁻_k) A₀ᵀ (A₀ = P⁺ Φᵀ P⁻⁻¹): the
  smoothed error of the node's prior nominal, in its own coordinates. Ps ≤ P⁺ holds at every node.

The smoothed outputs (:func:`.smoother.smooth_outputs`) between node k−1 and a node k with a feedback turn
interpolate towards ds_k + dx_k, which is then in the turned coordinates: over that one interval the tilt
part of the correction is turned by the node's heading correction (outputs at and after node k exact; the
difference is that correction times the tilt's, of second order unless the correction is large).
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np

from aidnav.jit import njit
from aidnav.nav.rotations import quat_from_rotvec, wrap_pi

from .ins_errors import turn_tilt_by
from .layout import PHI

__all__ = ["TILT_TURN_KEY", "turn_with_feedback", "keep_prior", "keep_post", "turn_rows_by", "turn_vector_by"]

#: a hash of this module's source, part of the ``depends`` key of the kernels that inline its kernels
#: (``engine.run_chunk``, ``engine_batch``): numba keys a cached kernel on its own source file only
TILT_TURN_KEY = hashlib.sha256(Path(__file__).read_bytes()).hexdigest()[:20]


@njit(cache=True, inline="always")  # per node: inlined in run_chunk
def turn_with_feedback(dx, P, turn, ix):
    """After the feedback of ``dx`` (``engine.feedback``): the tilt rows of P turned with its heading
    correction (:func:`.ins_errors.turn_tilt_by`; module doc) where ``turn``: at every moving node and
    wherever the heading is held unknown (before the first course alignment, after an IMU gap); at a static
    node ``engine._turn_tilt_at_rest`` turns it at the next node. The correction is the feedback rotation's
    part about Up (its twist, 2 atan2(q_U, q_0) of its quaternion, for R = R_U(ψ) R_tilt in either order),
    not the change of the body's Euler heading, which a tilt correction also moves where the body is not
    level (by ~ε tan θ at pitch θ). ``ix``: the index in P of each state of the full INS layout. Returns the
    turn as a heading change [rad] (0: none), which the RTS pass sees as part of the node
    (:func:`keep_post`)."""
    if not turn or ix[PHI] < 0 or ix[PHI + 1] < 0:
        return 0.0
    q = quat_from_rotvec(dx[PHI:PHI + 3])
    dh = -2.0 * np.arctan2(q[3], q[0])  # (a rotation about Up by ψ turns the heading by −ψ)
    turn_tilt_by(P, ix[PHI], ix[PHI + 1], dh)
    return dh


@njit(cache=True)
def turn_rows_by(M, ie, inn, dh):
    """The tilt's rows (φ_E, φ_N at ``ie``, ``inn``) of the matrix ``M`` turned with a heading change ``dh``
    [rad, clockwise from North] of the computed frame, in place: M ← T M, the rows of
    :func:`.ins_errors.turn_tilt_by`'s P ← T P Tᵀ (the rotation about Up by −dh)."""
    y = -wrap_pi(dh)
    c, s = np.cos(y), np.sin(y)
    for j in range(M.shape[1]):
        pe, pn = M[ie, j], M[inn, j]
        M[ie, j], M[inn, j] = c * pe - s * pn, s * pe + c * pn


@njit(cache=True)
def turn_vector_by(v, ie, inn, dh):
    """:func:`turn_rows_by` of a vector: v ← T v."""
    y = -wrap_pi(dh)
    c, s = np.cos(y), np.sin(y)
    pe, pn = v[ie], v[inn]
    v[ie], v[inn] = c * pe - s * pn, s * pe + c * pn


@njit(cache=True, inline="always")  # per node: inlined in run_chunk
def keep_prior(smooth, S, j, Phi, P, dh, ix):
    """Before node j's updates: P⁻ and the transition into it, T Φ where the node turned the tilt at rest by
    ``dh`` [rad] after the prediction (module doc). ``S``: (S_post, S_prior, S_phi, S_dx); ``ix``: the
    index in P of each state of the full INS layout."""
    if not smooth:
        return
    S[2][j], S[1][j] = Phi, P
    if dh != 0.0 and ix[PHI] >= 0 and ix[PHI + 1] >= 0:
        turn_rows_by(S[2][j], ix[PHI], ix[PHI + 1], dh)


@njit(cache=True, inline="always")  # per node: inlined in run_chunk
def keep_post(smooth, S, j, P, dx, dh, ix):
    """After node j's feedback: P⁺ and the update dx; where the feedback turned the tilt by ``dh`` [rad], the
    node's prior, transition and update in the turned coordinates of P⁺ (module doc)."""
    if not smooth:
        return
    S[0][j], S[3][j] = P, dx
    if dh != 0.0 and ix[PHI] >= 0 and ix[PHI + 1] >= 0:
        turn_tilt_by(S[1][j], ix[PHI], ix[PHI + 1], dh)
        turn_rows_by(S[2][j], ix[PHI], ix[PHI + 1], dh)
        turn_vector_by(S[3][j], ix[PHI], ix[PHI + 1], dh)
