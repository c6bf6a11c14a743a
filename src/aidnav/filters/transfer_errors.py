"""Errors of a transfer alignment against the simulation's truth (seed 004): per-epoch errors of every
state in the filter's definition (for NEES) and the segment statistics of the seed's tables. Frames and
units as :mod:`aidnav.filters.transfer` (ENU, body RFU; radians, metres, seconds)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from aidnav.nav.earth import lla_difference_enu, lla_to_ecef
from aidnav.nav.rotations import attitude_error_batch, euler_to_quat_batch, wrap_pi

from .transfer_model import BA, BG, DP, DV, N_INS, PHI, RHO, THETA, THETA_DOT

if TYPE_CHECKING:  # the simulator's containers, for annotations only (filters do not import sim)
    from aidnav.sim.distributed_pos import DistributedPosRun

    from .transfer import TransferResult

__all__ = ["TransferErrors", "transfer_errors", "segment_statistic"]


@dataclass
class TransferErrors:
    """Errors (estimate − truth) of a transfer alignment at its epochs.

    time (M,) [s]; rph (M, 3) roll, pitch, heading errors [rad] (wrapped); phi (M, 3) misalignment φ
    [rad] (rotation vector, docs/conventions.md sign); vel (M, 3) ENU [m/s]; pos (M, 3) E, N, U [m]
    (lat error as N, lon error as E); baseline (M,) error of the master–sub distance |p̃_s − p̃_m| [m]
    (master output position against the sub estimate); rho (M, 3), theta (M, 3), theta_dot (M, 3)
    errors of the estimates [rad, rad, rad/s]; state (M, n) errors of the full state vector in the
    filter's definition (for NEES).
    """

    time: np.ndarray
    rph: np.ndarray
    phi: np.ndarray
    vel: np.ndarray
    pos: np.ndarray
    baseline: np.ndarray
    rho: np.ndarray
    theta: np.ndarray
    theta_dot: np.ndarray
    state: np.ndarray


def transfer_errors(res: TransferResult, run: DistributedPosRun) -> TransferErrors:
    """Errors of ``res`` against the truth of ``run`` at the filter epochs."""
    idx = run.master.index[:len(res.time)]
    s = run.sub.truth
    d_rph = res.rph - s.rph[idx]
    d_rph = wrap_pi(d_rph)
    phi = attitude_error_batch(np.ascontiguousarray(res.state[:, 6:10]), euler_to_quat_batch(s.rph[idx]))
    dvel = res.state[:, 3:6] - s.vel[idx]
    de, dn, du = lla_difference_enu(res.state[:, 0], res.state[:, 1], res.state[:, 2], s.lat[idx], s.lon[idx],
                                    s.height[idx])
    pos = np.column_stack([de, dn, du])
    m = run.master
    M = len(res.time)
    ps = np.column_stack(lla_to_ecef(res.state[:, 0], res.state[:, 1], res.state[:, 2]))
    pm = np.column_stack(lla_to_ecef(m.lat[:M], m.lon[:M], m.height[:M]))
    ts = np.column_stack(lla_to_ecef(s.lat[idx], s.lon[idx], s.height[idx]))
    tm = np.column_stack(lla_to_ecef(run.master_truth.lat[idx], run.master_truth.lon[idx],
                                     run.master_truth.height[idx]))
    base = np.linalg.norm(ps - pm, axis=1) - np.linalg.norm(ts - tm, axis=1)
    drho = res.rho - run.sub.rho[None, :]
    dth = res.theta - run.sub.theta[idx]
    dthd = res.theta_dot - run.sub.theta_dot[idx]
    n = res.config.nstate
    x = np.zeros((M, n))
    x[:, PHI:PHI + 3] = phi
    x[:, DV:DV + 3] = dvel
    x[:, DP] = res.state[:, 0] - s.lat[idx]
    x[:, DP + 1] = res.state[:, 1] - s.lon[idx]
    x[:, DP + 2] = res.state[:, 2] - s.height[idx]
    # bias residual states are true − estimated
    x[:, BG:BG + 3] = run.sub.imu_errors["gyro_bias"][None, :] - res.bias[:, :3]
    x[:, BA:BA + 3] = run.sub.imu_errors["accel_bias"][None, :] - res.bias[:, 3:]
    # the filter's residual states are zero after feedback, so the error of the estimate is −(state)
    x[:, :N_INS] = -x[:, :N_INS]
    x[:, RHO:RHO + 3] = drho
    x[:, THETA:THETA + 3] = dth
    if n == 24:
        x[:, THETA_DOT:THETA_DOT + 3] = dthd
    return TransferErrors(time=res.time, rph=d_rph, phi=phi, vel=dvel, pos=pos, baseline=base, rho=drho,
                          theta=dth, theta_dot=dthd, state=x)


def segment_statistic(time: np.ndarray, err: np.ndarray, segments: list[dict], names=("AB", "CD"),
                      stat: str = "std") -> np.ndarray:
    """Mean over the named segments of a per-segment statistic of ``err`` ((M,) or (M, k)) over time.

    stat: "std" (standard deviation over the segment, about its mean: the seed's "STD") or "rms"
    (root mean square about zero). Epochs with start ≤ t ≤ end of a segment belong to it.
    """
    e = np.asarray(err, float)
    vals = []
    for name in names:
        row = next((r for r in segments if r["name"] == name), None)
        if row is None:
            raise KeyError(f"segment_statistic: no segment named {name!r}")
        msk = (time >= row["start_s"] - 1e-9) & (time <= row["end_s"] + 1e-9)
        seg = e[msk]
        if stat == "std":
            vals.append(np.std(seg, axis=0))
        elif stat == "rms":
            vals.append(np.sqrt(np.mean(seg**2, axis=0)))
        else:
            raise ValueError(f"segment_statistic: stat must be 'std' or 'rms', got {stat!r}")
    return np.mean(vals, axis=0)
