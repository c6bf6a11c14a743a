"""INS aided by sparse attitude fixes (e.g. the dipole-triad polarization attitude of seed 002).

A closed-loop 15-state error-state Kalman filter on the filter engine (:mod:`aidnav.filters.engine`:
strapdown at the IMU rate, covariance nodes every ``prop_dt`` and at every fix, the one gate policy
and feedback) with the attitude model :func:`aidnav.filters.measurements.attitude_model` (z from
C_computed C_measuredᵀ ≈ I − [z×], z ≈ φ − ε, the fix's full covariance as R) and the engine's
height / up-velocity hold (a baro-like aid).

Frames and units (``docs/conventions.md``): n = ENU, b = RFU, positions (lat, lon [rad], h [m]), velocity
ENU [m/s], attitude q_b^n; misalignment φ in n with C_b^n(computed) = (I − [φ×]) C_b^n(true); the
measurement noise of a fix is the covariance of ε with C_b^n(fix) = (I − [ε×]) C_b^n(true).
Closed-loop feedback after an update (as the loosely coupled filter, same function):
C_b^n ← (I + [φ̂×]) C_b^n, v ← v − δv̂, p ← p − δp̂, biases ← biases + ε̂, ∇̂.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from aidnav.nav.rotations import quat_to_euler_batch
from aidnav.units import DEG, DEG_H, UG

from . import measurements as ms
from .engine import NEVER, Imu, Init, Models, Output, Process, Records, run_filter
from .layout import make_layout
from .prior import ins_p0_diag, ins_psd, markov_psd
from .smoother import rts, smooth_outputs

__all__ = ["AttitudeFusionResult", "fuse_attitude_fixes", "imu_noise_psd", "initial_covariance_15"]



@dataclass
class AttitudeFusionResult:
    """Output of :func:`fuse_attitude_fixes`.

    time : (N,) IMU times [s]; states : (N, 10) strapdown states [lat, lon, h, vE, vN, vU, q_b^n];
    rph : (N, 3) roll, pitch, heading [rad]; std_att : (N, 3) 1σ of the misalignment φ (E, N, U) [rad]
    (of the last covariance node); gyro_bias : (N, 3) [rad/s]; accel_bias : (N, 3) [m/s²];
    fix_time : (M,) [s]; fix_innovation : (M, 3) [rad]; fix_nis : (M,); fix_accepted : (M,) bool.
    """

    time: np.ndarray
    states: np.ndarray
    rph: np.ndarray
    std_att: np.ndarray
    gyro_bias: np.ndarray
    accel_bias: np.ndarray
    fix_time: np.ndarray
    fix_innovation: np.ndarray
    fix_nis: np.ndarray
    fix_accepted: np.ndarray
    smoothed: bool = False
    forward_states: np.ndarray | None = None  #: (N, 10) forward solution when smoothed
    forward_std_att: np.ndarray | None = None


def imu_noise_psd(arw_deg_sqrt_h, vrw_m_s_sqrt_h, gyro_bias_instability_deg_h, accel_bias_instability_ug,
                  tau_s):
    """Continuous process-noise PSD vector (12,) of the 15-state model from boundary units
    (:func:`aidnav.filters.prior.ins_psd`): [ARW² ×3 (rad²/s), VRW² ×3 (m²/s³), 2σ_g²/τ ×3, 2σ_a²/τ ×3]
    (first-order Gauss–Markov biases)."""
    return ins_psd(arw_deg_sqrt_h * DEG / 60.0, vrw_m_s_sqrt_h / 60.0,
                   markov_psd(gyro_bias_instability_deg_h * DEG_H, tau_s),
                   markov_psd(accel_bias_instability_ug * UG, tau_s))


def initial_covariance_15(att_sigma_rad, vel_sigma_m_s, pos_sigma_m, gyro_bias_deg_h, accel_bias_ug, lat, h):
    """Diagonal P0 (15×15) (:func:`aidnav.filters.prior.ins_p0_diag`): attitude [rad] (3 or scalar),
    velocity [m/s], position [m] (E, N, U → δL, δλ, δh), gyro bias [deg/h], accelerometer bias [µg]."""
    gb = np.broadcast_to(np.asarray(gyro_bias_deg_h, float), (3,)) * DEG_H
    ab = np.broadcast_to(np.asarray(accel_bias_ug, float), (3,)) * UG
    return np.diag(ins_p0_diag(15, lat, h, att_sigma_rad, vel_sigma_m_s, pos_sigma_m, gb, ab))


def fuse_attitude_fixes(imu, state0, fix_time, fix_C_bn, fix_cov, q_psd, P0, tau_g=3600.0, tau_a=3600.0,
                        prop_dt=1.0, gate=0.0, hold_h=None, hold_vu=None,
                        use_fixes=True, smooth: bool = False) -> AttitudeFusionResult:
    """Strapdown INS with attitude fixes in a closed-loop 15-state error-state Kalman filter.

    Parameters
    ----------
    imu : :class:`aidnav.data.ImuData` (increments, body RFU; sample k covers (t_{k-1}, t_k], t_{-1}=imu.t0).
    state0 : (10,) strapdown state at ``imu.t0`` (:func:`aidnav.nav.strapdown.make_state`).
    fix_time : (M,) [s]; fix_C_bn : (M, 3, 3) measured C_b^n; fix_cov : (M, 3, 3) covariance [rad²] of the
        fix's misalignment ε in n (e.g. :attr:`aidnav.estimators.polarization.AttitudeFix.cov_eps`).
        A fix is applied at the first IMU sample at or after its time; the body rotation over the gap is
        taken from that sample's gyro increment (C(t_k) ≈ C(t_fix) exp([ω (t_k − t_fix)×]), Earth and
        transport rate over < 1 interval neglected).
    q_psd : (12,) continuous noise PSD (:func:`imu_noise_psd`); P0 : (15, 15) initial covariance
        (:func:`initial_covariance_15`); tau_g, tau_a : bias correlation times [s] (≤ 0: random walk).
    prop_dt : covariance propagation interval [s]; gate : chi-square gate on the fix NIS (≤ 0: off).
    hold_h, hold_vu : (N,) arrays to hold height and up velocity to (a baro-like aid), or None.
    use_fixes : False runs the free INS (same code path, the "INS only" reference).
    smooth : also run the engine's RTS pass; states, σ and biases are then the smoothed ones (the forward
        solution in ``forward_states`` / ``forward_std_att``).
    """
    time = np.ascontiguousarray(imu.time, dtype=float)
    N = time.shape[0]
    fix_time = np.asarray(fix_time, dtype=float).reshape(-1)
    M = fix_time.shape[0]
    rows = np.column_stack([np.asarray(fix_C_bn, dtype=float).reshape(M, 9),
                            np.asarray(fix_cov, dtype=float).reshape(M, 9)])
    # covariance nodes on the grid t0 + j·prop_dt (records that only schedule a node: use = False) and at
    # every fix; a fix is applied at the first IMU sample at or after its time (1 ns tolerance)
    grid = imu.t0 + prop_dt * np.arange(1, int((time[-1] - imu.t0) / prop_dt) + 1)
    t_all = np.concatenate([fix_time, grid]) - 1e-9
    o = np.argsort(t_all, kind="stable")
    rows_all = np.vstack([rows, np.zeros((len(grid), 18))])
    use = np.concatenate([np.full(M, bool(use_fixes)), np.zeros(len(grid), bool)])
    rec = Records(np.ascontiguousarray(t_all[o]), np.full(len(o), ms.M_ATT, np.int64),
                  np.ascontiguousarray(rows_all[o]), np.ascontiguousarray(use[o]))
    pos = np.empty(len(o), np.int64)
    pos[o] = np.arange(len(o))
    pos = pos[:M]  # log row of each fix
    gates = np.zeros((ms.N_MODELS, ms.MAX_ROWS + 1))
    gates[ms.M_ATT, 3] = max(float(gate), 0.0)
    never = np.full(ms.N_MODELS, NEVER, np.int64)  # no consecutive-rejection rule
    mod = Models(np.zeros((ms.N_MODELS, 1)), gates, never, np.zeros((0, 2), np.int64))
    lay = make_layout(False)
    proc = Process(lay, np.asarray(q_psd, dtype=float), np.array([tau_g, tau_a, 0.0, 0.0]), np.zeros(0),
                   float(prop_dt))
    st0 = np.asarray(state0, dtype=float).copy()
    ini = Init(float(imu.t0), st0, np.zeros(6), np.asarray(P0, dtype=float).copy(), -1, 0.0, 0.0,
               np.full(15, np.nan))
    hold = np.zeros((0, 2)) if hold_h is None else np.column_stack([hold_h, hold_vu]).astype(float)
    dth, dv = np.ascontiguousarray(imu.dtheta, dtype=float), np.ascontiguousarray(imu.dv, dtype=float)
    imu_in = Imu(time, dth, dv, np.zeros(N, np.bool_), np.zeros((N, 2)), np.ascontiguousarray(hold))
    r = run_filter(imu_in, rec, mod, proc, ini, Output(1, bool(smooth), np.zeros(0, np.int64)))
    # σ and biases of the node that closes each sample's interval (as before the engine)
    j = np.minimum(np.searchsorted(r.node_idx, np.arange(N)), len(r.node_idx) - 1)
    nxt = r.node_idx[j]
    std_att = np.sqrt(np.maximum(r.out_pdiag[nxt, 0:3], 0.0))
    states, bias = r.out_st, r.out_bias
    fwd = (None, None)
    if smooth and len(r.node_idx) > 1:
        ds, Ps = rts(r.S_post, r.S_prior, r.S_phi, r.S_dx, r.reset_node)
        states, bias = smooth_outputs(r.out_idx, r.out_st, r.out_bias, r.out_node, r.node_idx, ds, r.S_dx, 15)
        fwd = (r.out_st, std_att)
        std_att = np.sqrt(np.maximum(np.einsum("kii->ki", Ps)[j, 0:3], 0.0))
    f_innov, f_nis, f_acc = np.full((M, 3), np.nan), np.full(M, np.nan), np.zeros(M, bool)
    f_innov[:], f_nis[:], f_acc[:] = r.log.nu[pos, :3], r.log.nis[pos], r.log.status[pos] == 1
    rph = quat_to_euler_batch(np.ascontiguousarray(states[:, 6:10]))
    return AttitudeFusionResult(time, states, rph, std_att, bias[nxt, 0:3], bias[nxt, 3:6], fix_time, f_innov,
                                f_nis, f_acc, fwd[0] is not None, fwd[0], fwd[1])
