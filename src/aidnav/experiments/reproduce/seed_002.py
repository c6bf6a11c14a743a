"""Reproduction of seed 002: aircraft attitude from a dipole triad and one base station (§3).

What is rebuilt (seed §6, Fig. 2, and §3.7's acceptance targets):

* **Fig. 2** — the seed's flight: heading turning through 90° while the roll oscillates and the pitch
  stays 0; 36 attitude fixes, each from 1000 snapshots of an η = 27° elliptically polarized signal at
  SNR 10 dB; (a–c) true, closed-form and ML roll/heading/pitch of one realisation; (d–f) Monte Carlo
  std (``runs`` realisations per fix, 60 in the seed) of the closed form and the ML against the CRB.
  Written as ``fig2_attitude_estimates.png`` and ``fig2_attitude_std.png``, plus ``fig2_cvae.png`` (the
  rotation-vector errors about u, ṽ1, ṽ2 against the CVAE bound, which is the same at every fix).
* **Sweeps** (not in the seed; they test its CRB claims): std of the three rotation-vector components vs
  SNR, vs the number of snapshots N and vs η, ML and closed form against the CRB
  (``sweep_snr.png``, ``sweep_n.png``, ``sweep_eta.png``).
* **INS fusion** (the seed's conclusion suggests Kalman filtering): a low-grade INS flown through the
  same flight, aided by the 36 polarization attitude fixes in the 15-state error-state filter
  (:func:`aidnav.filters.attitude_aiding.fuse_attitude_fixes`), against the free INS
  (``fusion_attitude_error.png``).

The flight (the seed gives only its shape): 100 m/s level coordinated flight at 1000 m, heading from
315° (−45°) to 45° through six 30-s cycles of a 20-s right turn and a 10-s left turn at 1.5°/s (bank
±15°), pitch 0; a fix every 5 s (t = 2.5, 7.5, …, 177.5 s). The base station is on the ground 30 km
North of the start and transmits with its major axis horizontal (γ′ = 0), so that in mid-flight the
nose points along the line of sight, the major axis lies along the wings and the minor axis is vertical:
the geometry in which §3.5 reads the CVAE components (u, ṽ1, ṽ2) as (roll, pitch, heading).

Errata followed (§3.6): FLU body axes (1), θ ∈ [−π/2, π/2] (2), corrected eq. (3) (3), Stokes tilt
instead of eq. (4) (4), complex-Gaussian likelihood (5), corrected eq. (9) with Ry(−θ′) (6), CVAE without
the leading N and with (u, ṽ1, ṽ2) components (7), the line-of-sight ambiguity resolved by "upright" (8).
Physics over the seed: the base's and the aircraft's geographic frames are related by the exact
rotation between them (the seed's flat Earth would err by ≈ 0.1–0.3° here).
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from scipy.stats import chi2

from aidnav.data import ImuData
from aidnav.estimators.polarization import (
    closed_form,
    closed_form_covariance,
    crb_attitude,
    crb_rotation_vector,
    cvae_bound,
    estimate_attitude,
    ml_estimate,
    resolve_line_of_sight,
)
from aidnav.experiments.reproduce._study import Study, main, mean_se
from aidnav.experiments.reproduce.summary import summary_row, summary_table
from aidnav.filters.attitude_aiding import fuse_attitude_fixes, imu_noise_psd, initial_covariance_15
from aidnav.nav.earth import radii
from aidnav.nav.rotations import (
    dcm_from_euler,
    dcm_from_quat,
    euler_from_dcm,
    quat_from_dcm,
    rotvec_from_dcm,
    wrap_2pi,
    wrap_pi,
)
from aidnav.nav.strapdown import make_state
from aidnav.nav.wave_frame import P_SEED, base_wave_dcm, wave_dcm
from aidnav.sim.dipole_triad import (
    base_geometry,
    sample_covariance,
    simulate_snapshots,
    wave_params_for_attitude,
)
from aidnav.sim.imu import ImuSpec, corrupt_imu
from aidnav.sim.motion import generate, half_widths
from aidnav.units import DEG

SEED = "002"
TITLE = ("Aircraft attitude/heading estimation using a dipole triad antenna (He, Chen, Zhang; "
         "J. Radars 2012)")

# the seed's simulation (§6)
ETA = 27.0 * DEG
SNR_DB = 10.0
N_SNAP = 1000
N_FIXES = 36
TX_TILT = 0.0
# §3.7 CVAE CRB σ [deg] about (u, ṽ1, ṽ2)
SPEC_CVAE_DEG = (0.7229, 0.9360, 0.4769)
ANGLES = ("roll", "pitch", "heading")
AXES_W = ("u", "ṽ1", "ṽ2")


# ============================================================================ the flight
@dataclass
class SeedFlight:
    """Truth of the seed-002 flight and its base-station geometry at the fixes.

    time, lat, lon, h, vel, rph : truth at the IMU epochs (rad, m, m/s); imu : exact increments;
    fix_idx : (K,) indices of the fixes into ``time``; C_true : (K, 3, 3) C_b^n at the fixes;
    bearing, elevation : (K,) of the aircraft seen from the base [rad]; base_to_local : (K, 3, 3);
    wave : (K, 3) true (φ, θ, γ) in the seed frame I [rad]; base : (lat, lon, h) of the base.
    """

    time: np.ndarray
    lat: np.ndarray
    lon: np.ndarray
    h: np.ndarray
    vel: np.ndarray
    rph: np.ndarray
    imu: ImuData
    fix_idx: np.ndarray
    C_true: np.ndarray
    bearing: np.ndarray
    elevation: np.ndarray
    base_to_local: np.ndarray
    wave: np.ndarray
    base: tuple

    @property
    def fix_time(self):
        return self.time[self.fix_idx]


def seed_flight(rate_hz: float = 100.0, fix_period: float = 5.0, n_fixes: int = N_FIXES) -> SeedFlight:
    """The flight of the module docstring: truth, exact IMU increments and the geometry at the fixes."""
    lat0, lon0, h0, v = 32.0 * DEG, 118.8 * DEG, 1000.0, 100.0
    rate = 1.5 * DEG
    n_cycles = int(np.ceil(n_fixes * fix_period / 30.0))
    durs, turns = [], []
    for _ in range(n_cycles):
        durs += [20.0, 10.0]
        turns += [rate, -rate]
    tb = np.concatenate([[0.0], np.cumsum(durs)[:-1]])
    vals = np.zeros((len(tb), 3))
    vals[:, 1] = turns
    half = half_widths(tb, 4.0)
    dt = 1.0 / rate_hz
    n = int(round(sum(durs) * rate_hz))
    y0 = np.array([lat0, lon0, h0, v, -45.0 * DEG, 0.0])
    tr, dth, dvv = generate(tb, half, vals, y0, 0.0, dt, n)
    time = np.arange(n + 1) * dt
    rph = np.column_stack([tr[:, 7], tr[:, 8], wrap_2pi(tr[:, 9])])
    imu = ImuData(time=time[1:].copy(), dtheta=dth, dv=dvv, t0=0.0)
    rm, _ = radii(lat0)
    base = (lat0 + 30000.0 / (rm + 0.0), lon0, 0.0)
    fix_idx = np.round((fix_period * (np.arange(n_fixes) + 0.5)) * rate_hz).astype(int)
    K = n_fixes
    C_true = np.empty((K, 3, 3))
    bearing = np.empty(K)
    elev = np.empty(K)
    b2l = np.empty((K, 3, 3))
    wave = np.empty((K, 3))
    for j, k in enumerate(fix_idx):
        C_true[j] = dcm_from_euler(*rph[k])
        bearing[j], elev[j], _, b2l[j] = base_geometry(*base, tr[k, 1], tr[k, 2], tr[k, 3])
        wave[j] = wave_params_for_attitude(C_true[j], bearing[j], elev[j], TX_TILT, b2l[j])
    return SeedFlight(time, tr[:, 1].copy(), tr[:, 2].copy(), tr[:, 3].copy(),
                      np.ascontiguousarray(tr[:, 4:7]), rph, imu, fix_idx, C_true, bearing, elev, b2l, wave,
                      base)


# ============================================================================ estimation helpers
def _eps_and_rph_error(C_est, C_true):
    """Misalignment ε in n (C_est = (I − [ε×]) C_true) and Euler errors (est − true, wrapped) [rad]."""
    eps = rotvec_from_dcm(np.ascontiguousarray(C_true @ C_est.T))
    e = np.array(euler_from_dcm(C_est)) - np.array(euler_from_dcm(C_true))
    return eps, wrap_pi(e)


def _fix_geometry_G(fl: SeedFlight, j: int):
    """ε = G δ: wave-frame rotation (about u, ṽ1, ṽ2) → misalignment in the aircraft's n."""
    return fl.base_to_local[j] @ P_SEED @ base_wave_dcm(-fl.bearing[j], fl.elevation[j], TX_TILT)


def _attitude(fl: SeedFlight, j: int, params, prior=None):
    _, C, _ = resolve_line_of_sight(params[0], params[1], params[2], fl.bearing[j], fl.elevation[j],
                                    TX_TILT, prior, fl.base_to_local[j])
    return C


def monte_carlo_fixes(fl: SeedFlight, runs: int, rng: np.random.Generator, eta=ETA, snr_db=SNR_DB,
                      n_snap=N_SNAP) -> dict:
    """Closed-form (single snapshot and principal eigenvector) and ML attitude at every fix, ``runs`` times.

    Returns arrays (runs, K, 3) of Euler errors ``rph_err_*`` [rad], wave-frame rotation errors
    ``delta_*`` [rad] (about u, ṽ1, ṽ2), estimated (roll, pitch, heading) ``rph_*`` [rad], for
    * in (snap, cf, ml); and the CRB σ of (roll, pitch, heading) per fix ``crb_rph`` (K, 3) [rad].
    """
    K = len(fl.fix_idx)
    out = {f"{q}_{m}": np.empty((runs, K, 3))
           for q in ("rph_err", "delta", "rph") for m in ("snap", "cf", "ml")}
    crb = np.empty((K, 3))
    rho = 10.0 ** (snr_db / 10.0)
    for j in range(K):
        _, cov_rph, _ = crb_attitude(*fl.wave[j], eta, rho, n_snap, fl.bearing[j], fl.elevation[j], TX_TILT,
                                     fl.base_to_local[j])
        crb[j] = np.sqrt(np.diag(cov_rph))
    for r in range(runs):
        for j in range(K):
            S = simulate_snapshots(*fl.wave[j], eta, snr_db, n_snap, rng)
            R = sample_covariance(S)
            cf = closed_form_covariance(R, eta)
            ests = {"snap": closed_form(S[0], eta), "cf": cf, "ml": ml_estimate(R, eta, start=cf).params}
            G = _fix_geometry_G(fl, j)
            for m, p in ests.items():
                C = _attitude(fl, j, [float(x) for x in p])
                eps, erph = _eps_and_rph_error(C, fl.C_true[j])
                out[f"rph_err_{m}"][r, j] = erph
                out[f"delta_{m}"][r, j] = G.T @ eps
                out[f"rph_{m}"][r, j] = euler_from_dcm(C)
    out["crb_rph"] = crb
    return out


def sweep(rng: np.random.Generator, runs: int, snr_db_list=(SNR_DB,), n_list=(N_SNAP,), eta_list=(ETA,),
          wave=(30 * DEG, 20 * DEG, 15 * DEG)) -> list[dict]:
    """Std of the wave-frame rotation errors δ (about u, ṽ1, ṽ2) of closed form and ML vs the CVAE CRB over
    the Cartesian product of SNR [dB], N and η [rad] at one DOA/tilt ``wave`` [rad]. One dict per point:
    snr_db, n, eta_deg, crb (3,), std_cf (3,), std_ml (3,) [rad] (RMS about the truth), bias_ml (3,)."""
    C0 = wave_dcm(*wave)
    rows = []
    for s in snr_db_list:
        for n in n_list:
            for eta in eta_list:
                d = {"cf": np.empty((runs, 3)), "ml": np.empty((runs, 3))}
                for r in range(runs):
                    R = sample_covariance(simulate_snapshots(*wave, eta, s, int(n), rng))
                    cf = closed_form_covariance(R, eta)
                    for m, p in (("cf", cf), ("ml", ml_estimate(R, eta, start=cf).params)):
                        # nearest of γ, γ+π to the truth (the sweep measures accuracy, not ambiguity)
                        Ce = wave_dcm(*p)
                        Cf = wave_dcm(p[0], p[1], p[2] + np.pi)
                        dl = [-rotvec_from_dcm(np.ascontiguousarray(X @ C0.T)) for X in (Ce, Cf)]
                        d[m][r] = min(dl, key=np.linalg.norm)
                crb = np.sqrt(np.diag(cvae_bound(eta, 10 ** (s / 10), n)))
                rows.append({"snr_db": float(s), "n": int(n), "eta_deg": float(eta / DEG), "crb": crb,
                             "std_cf": np.sqrt(np.mean(d["cf"] ** 2, 0)),
                             "std_ml": np.sqrt(np.mean(d["ml"] ** 2, 0)), "bias_ml": np.mean(d["ml"], 0),
                             "runs": runs})
    return rows


def fusion_case(fl: SeedFlight, runs: int, rng: np.random.Generator, eta=ETA, snr_db=SNR_DB,
                n_snap=N_SNAP) -> dict:
    """Low-grade INS with and without the polarization attitude fixes (ML), ``runs`` Monte Carlo runs.

    IMU (1σ): gyro bias 50 deg/h, ARW 0.3 deg/√h, accel bias 1000 µg, VRW 0.1 m/s/√h; initial attitude
    error 1° per axis; height held to the truth (a baro). Returns the misalignment errors ε (runs, N, 3)
    [rad] of ``fused`` and ``ins`` and the fused filter σ, the fix errors, and the time axis.
    """
    spec = ImuSpec.from_units(gyro_bias_deg_h=50.0, arw_deg_sqrt_h=0.3, accel_bias_ug=1000.0,
                              vrw_m_s_sqrt_h=0.1)
    q = imu_noise_psd(0.3, 0.1, 1.0, 10.0, 3600.0)
    P0 = initial_covariance_15(1.0 * DEG, 0.1, 1.0, 50.0, 1000.0, fl.lat[0], fl.h[0])
    N = len(fl.imu.time)
    K = len(fl.fix_idx)
    res = {"fused": np.empty((runs, N, 3)), "ins": np.empty((runs, N, 3)), "std": np.empty((runs, N, 3)),
           "fix_err": np.empty((runs, K, 3)), "nis": np.empty((runs, K))}
    q_true = np.array([quat_from_dcm(dcm_from_euler(*r)) for r in fl.rph[1:]])
    for r in range(runs):
        imu, _ = corrupt_imu(fl.imu, spec, rng)
        att0 = dcm_from_euler(*fl.rph[0])
        e0 = rng.standard_normal(3) * DEG
        C0 = (np.eye(3) - np.array([[0, -e0[2], e0[1]], [e0[2], 0, -e0[0]], [-e0[1], e0[0], 0]])) @ att0
        C0 = dcm_from_quat(quat_from_dcm(C0))
        st0 = make_state(fl.lat[0], fl.lon[0], fl.h[0], fl.vel[0], quat_from_dcm(C0))
        Cf = np.empty((K, 3, 3))
        Rf = np.empty((K, 3, 3))
        for j in range(K):
            S = simulate_snapshots(*fl.wave[j], eta, snr_db, n_snap, rng)
            fix = estimate_attitude(sample_covariance(S), n_snap, eta, fl.bearing[j], fl.elevation[j],
                                    TX_TILT, base_to_local=fl.base_to_local[j])
            Cf[j] = fix.C_bn
            Rf[j] = fix.cov_eps
            res["fix_err"][r, j] = rotvec_from_dcm(np.ascontiguousarray(fl.C_true[j] @ fix.C_bn.T))
        hold = (fl.h[1:], fl.vel[1:, 2])
        fused = fuse_attitude_fixes(imu, st0, fl.fix_time, Cf, Rf, q, P0, hold_h=hold[0], hold_vu=hold[1])
        ins = fuse_attitude_fixes(imu, st0, fl.fix_time, Cf, Rf, q, P0, hold_h=hold[0], hold_vu=hold[1],
                                  use_fixes=False)
        for name, fr in (("fused", fused), ("ins", ins)):
            qe = np.ascontiguousarray(fr.states[:, 6:10])
            for k in range(N):
                res[name][r, k] = rotvec_from_dcm(
                    np.ascontiguousarray(dcm_from_quat(q_true[k]) @ dcm_from_quat(qe[k]).T))
        res["std"][r] = fused.std_att
        res["nis"][r] = fused.fix_nis
    res["time"] = fl.imu.time
    res["fix_time"] = fl.fix_time
    return res


# ============================================================================ statistics
def _lit(x) -> str:
    """A number as it appears in a target expression (6 significant digits)."""
    return f"{float(x):.6g}"


def chi2_std_bounds(n: int, prob: float) -> tuple[float, float]:
    """Two-sided ``prob`` interval of the ratio (RMS of n unbiased N(0, σ²) errors)/σ: sqrt(χ²_n/n)."""
    a = 0.5 * (1.0 - prob)
    return float(np.sqrt(chi2.ppf(a, n) / n)), float(np.sqrt(chi2.ppf(1.0 - a, n) / n))


# ============================================================================ figures
def _fig(nrows, ncols, w=11.0, h=6.5):
    fig = Figure(figsize=(w, h), layout="constrained")
    FigureCanvasAgg(fig)
    return fig, fig.subplots(nrows, ncols, squeeze=False)


def _plot_fig2(mc, fl, out: Path) -> list[str]:
    K = len(fl.fix_idx)
    x = np.arange(1, K + 1)
    order = (0, 2, 1)  # the seed's panels: roll, heading, pitch
    true = np.array([euler_from_dcm(C) for C in fl.C_true])
    fig, ax = _fig(1, 3, h=3.8)
    for c, i in enumerate(order):
        a = ax[0, c]
        wrap = wrap_pi if i == 2 else np.asarray  # heading shown in [−180°, 180°)
        a.plot(x, wrap(true[:, i]) / DEG, ".-", color="k", lw=0.8, label="true")
        a.plot(x, wrap(mc["rph_cf"][0, :, i]) / DEG, "x", color="tab:blue", label="closed form (eigenvector)")
        a.plot(x, wrap(mc["rph_ml"][0, :, i]) / DEG, "o", mfc="none", color="tab:red", label="ML")
        a.set_title(f"({'abc'[c]}) {ANGLES[i]}")
        a.set_xlabel("fix number")
        a.set_ylabel(f"{ANGLES[i]} [deg]")
        a.grid(alpha=0.3)
    ax[0, 0].legend(fontsize="small")
    fig.suptitle("Seed 002 Fig. 2(a–c): attitude of one realisation (η = 27°, SNR 10 dB, N = 1000)")
    fig.savefig(out / "fig2_attitude_estimates.png", dpi=110)

    fig, ax = _fig(1, 3, h=3.8)
    runs = mc["rph_err_ml"].shape[0]
    for c, i in enumerate(order):
        a = ax[0, c]
        a.plot(x, mc["crb_rph"][:, i] / DEG, ".-", color="k", label="CRB")
        for m, sty, col, lab in (("snap", "+", "0.6", "closed form, 1 snapshot (seed eqs. 2–4)"),
                                 ("cf", "x", "tab:blue", "closed form, eigenvector"),
                                 ("ml", "o", "tab:red", "ML")):
            a.plot(x, np.sqrt(np.mean(mc[f"rph_err_{m}"][:, :, i] ** 2, 0)) / DEG, sty, color=col,
                   mfc="none", label=lab)
        if ANGLES[i] == "pitch":  # the seed's only printed number: "pitch worst, about 1°"
            a.axhline(1.0, color="tab:green", ls="--", lw=1.0, label="seed: pitch ≈ 1° (worst)")
            a.legend(fontsize="x-small")
        a.set_yscale("log")
        a.set_title(f"({'def'[c]}) {ANGLES[i]} std, {runs} runs")
        a.set_xlabel("fix number")
        a.set_ylabel("std [deg]")
        a.grid(alpha=0.3, which="both")
    ax[0, 0].legend(fontsize="small")
    fig.suptitle("Seed 002 Fig. 2(d–f): Monte Carlo std vs the CRB (geometry-dependent Euler-angle CRB)")
    fig.savefig(out / "fig2_attitude_std.png", dpi=110)

    fig, ax = _fig(1, 3, h=3.6)
    cv = np.sqrt(np.diag(cvae_bound(ETA, 10 ** (SNR_DB / 10), N_SNAP))) / DEG
    for i in range(3):
        a = ax[0, i]
        a.axhline(cv[i], color="k", label="CVAE CRB")
        for m, sty, col, lab in (("cf", "x", "tab:blue", "closed form, eigenvector"),
                                 ("ml", "o", "tab:red", "ML")):
            a.plot(x, np.sqrt(np.mean(mc[f"delta_{m}"][:, :, i] ** 2, 0)) / DEG, sty, color=col, mfc="none",
                   label=lab)
        a.set_title(f"rotation about {AXES_W[i]}")
        a.set_xlabel("fix number")
        a.set_ylabel("std [deg]")
        a.set_ylim(0, 1.6 * cv[i])
        a.grid(alpha=0.3)
    ax[0, 0].legend(fontsize="small")
    fig.suptitle("Wave-frame rotation-vector errors vs the CVAE bound (independent of geometry)")
    fig.savefig(out / "fig2_cvae.png", dpi=110)
    return ["fig2_attitude_estimates.png", "fig2_attitude_std.png", "fig2_cvae.png"]


def _plot_sweep(rows, key, xlabel, fname, out: Path, logx=False):
    fig, ax = _fig(1, 3, h=3.6)
    xs = np.array([r[key] for r in rows])
    for i in range(3):
        a = ax[0, i]
        a.plot(xs, [r["crb"][i] / DEG for r in rows], "-", color="k", label="CRB")
        a.plot(xs, [r["std_cf"][i] / DEG for r in rows], "x", color="tab:blue", label="closed form")
        a.plot(xs, [r["std_ml"][i] / DEG for r in rows], "o", mfc="none", color="tab:red", label="ML")
        a.set_yscale("log")
        if logx:
            a.set_xscale("log")
        a.set_xlabel(xlabel)
        a.set_ylabel("std [deg]")
        a.set_title(f"rotation about {AXES_W[i]}")
        a.grid(alpha=0.3, which="both")
    ax[0, 0].legend(fontsize="small")
    fig.suptitle(f"std vs {xlabel} ({rows[0]['runs']} runs per point)")
    fig.savefig(out / fname, dpi=110)
    return fname


def _plot_fusion(fu, out: Path) -> str:
    fig, ax = _fig(3, 1, w=10, h=8)
    t = fu["time"]
    for i, name in enumerate(("East", "North", "Up (≈ heading)")):
        a = ax[i, 0]
        a.plot(t, fu["ins"][0, :, i] / DEG, color="0.5", lw=0.9, label="INS only")
        a.plot(t, fu["fused"][0, :, i] / DEG, color="tab:red", lw=0.9, label="INS + polarization fixes")
        a.fill_between(t, -3 * fu["std"][0, :, i] / DEG, 3 * fu["std"][0, :, i] / DEG, color="tab:red",
                       alpha=0.15, lw=0, label="±3σ (filter)")
        a.plot(fu["fix_time"], fu["fix_err"][0, :, i] / DEG, "o", ms=3, mfc="none", color="tab:blue",
               label="fix error (ML)")
        a.set_ylabel(f"ε {name} [deg]")
        a.grid(alpha=0.3)
    ax[0, 0].legend(fontsize="small", ncol=4)
    ax[2, 0].set_xlabel("time [s]")
    fig.suptitle("Attitude misalignment ε (C_est = (I − [ε×]) C_true), run 0")
    fig.savefig(out / "fusion_attitude_error.png", dpi=110)
    return "fusion_attitude_error.png"


# ============================================================================ run
def _fig2_table(mc: dict, fl, runs: int, tol: float) -> dict:
    """Fig. 2: the CVAE CRB formula checks, the ML and closed-form estimators against it, their biases and
    the seed's ordering; ``tol``: the pooled ML std tolerance."""
    rho = 10 ** (SNR_DB / 10)
    cv = np.sqrt(np.diag(cvae_bound(ETA, rho, N_SNAP))) / DEG
    cv_geo = np.sqrt(np.diag(crb_rotation_vector(*fl.wave[N_FIXES // 2], ETA, rho, N_SNAP))) / DEG
    rows2 = []
    for i in range(3):
        rows2.append(summary_row(f"formula check: CVAE CRB σ about {AXES_W[i]} ({ANGLES[i]} in the seed's "
                                 "geometry) against the value COMPUTED in SPEC §3.7 from the seed's eq. (7) "
                                 "(not a number the paper prints)", "deg", cv[i], None,
                                 target="abs(ours - computed) <= 0.0005",
                                 values={"computed": SPEC_CVAE_DEG[i]}, spec=True, runs=0))
    rows2.append(summary_row("max relative |J·CRB_eq7·Jᵀ − CVAE| at mid-flight (eq. 7 through the DOA "
                             "Jacobian = the closed-form CVAE)", "-", float(np.max(np.abs(cv_geo - cv) / cv)),
                             target="ours < 1e-9", runs=0))
    n_pool = runs * N_FIXES
    for i in range(3):
        r_ml = float(np.sqrt(np.mean(mc["delta_ml"][:, :, i] ** 2)) / (cv[i] * DEG))
        se = r_ml / np.sqrt(2 * n_pool)  # a std estimated from n Gaussian samples: relative se 1/√(2n)
        rows2.append(summary_row(f"ML std / CVAE CRB about {AXES_W[i]} (pooled {N_FIXES} fixes × "
                                 f"{runs} runs)",
                                 "-", r_ml, target=f"abs(ours - 1) <= {tol}", spec=True, stderr=se,
                                 margin=(tol - abs(r_ml - 1.0), se)))
    for i in range(3):
        z = mc["rph_err_ml"][:, :, i] / mc["crb_rph"][None, :, i]
        zr = float(np.sqrt(np.mean(z**2)))
        rows2.append(summary_row(f"ML {ANGLES[i]} std / Euler-angle CRB of each fix (pooled)", "-",
                                 zr, target=f"abs(ours - 1) <= {tol}", stderr=zr / np.sqrt(2 * n_pool)))
    for i in range(3):
        b, se = mean_se(mc["rph_err_ml"][:, :, i].ravel() / DEG)
        rows2.append(summary_row(f"ML {ANGLES[i]} bias (pooled)", "deg", b, target="abs(ours) < 0.1",
                                 spec=True, stderr=se))
    std_ml = np.sqrt(np.mean(mc["rph_err_ml"] ** 2, axis=(0, 1))) / DEG
    std_sn = np.sqrt(np.mean(mc["rph_err_snap"] ** 2, axis=(0, 1))) / DEG
    se_ml = std_ml / np.sqrt(2 * n_pool)
    for i in range(3):
        extra = " (seed: pitch worst ≈ 1°)" if i == 1 else ""
        rows2.append(summary_row(f"ML {ANGLES[i]} std over the flight{extra}", "deg", std_ml[i],
                                 paper=1.0 if i == 1 else None, stderr=se_ml[i]))
    # the seed's ordering, one predicate counted once: pitch > roll > heading
    gaps = [(std_ml[1] - std_ml[0], np.hypot(se_ml[1], se_ml[0])),
            (std_ml[0] - std_ml[2], np.hypot(se_ml[0], se_ml[2]))]
    g = min(gaps, key=lambda x: x[0] / x[1])
    rows2.append(summary_row("ML std ordering pitch > roll > heading (seed: 'pitch worst, heading best'); "
                             "ours = the smaller gap", "deg", float(min(x[0] for x in gaps)), None,
                             "pitch > roll and roll > heading",
                             {"pitch": std_ml[1], "roll": std_ml[0], "heading": std_ml[2]},
                             margin=(float(g[0]), float(g[1]))))
    lo, _ = chi2_std_bounds(runs * N_FIXES, 0.99)
    for i in range(3):
        z_cf = float(np.sqrt(np.mean((mc["delta_cf"][:, :, i] / (cv[i] * DEG)) ** 2)))
        z_ml = float(np.sqrt(np.mean((mc["delta_ml"][:, :, i] / (cv[i] * DEG)) ** 2)))
        rows2.append(summary_row(f"closed form (principal eigenvector) std / CVAE CRB about {AXES_W[i]} "
                                 "(≥ CRB within χ² 99 % sampling, close to ML)", "-", z_cf,
                                 target=f"ours >= {_lit(lo)} and ours <= 1.25 * {_lit(z_ml)}", spec=True,
                                 stderr=z_cf / np.sqrt(2 * n_pool)))
    for i in range(3):
        rows2.append(summary_row(f"single-snapshot closed form (seed eqs. 2–4 corrected) {ANGLES[i]} std",
                                 "deg", std_sn[i], target=f"ours > {_lit(std_ml[i])}", spec=True))
    return summary_table("Fig. 2", f"36 fixes, η = 27°, SNR 10 dB, N = 1000, {runs} Monte Carlo runs per "
                            "fix; the seed prints only 'pitch worst, ≈ 1°; heading best'; runs 0 (–): a "
                            "formula, no Monte Carlo",
                            rows2, runs=runs)


def _sweeps(rng_s: np.random.Generator, sweep_runs: int, out: Path) -> tuple[list[str], dict]:
    """The SNR, N and η sweeps of the ML std against the CRB → (their figures, their table)."""
    sw_snr = sweep(rng_s, sweep_runs, snr_db_list=(-5, 0, 5, 10, 15, 20, 25, 30))
    sw_n = sweep(rng_s, sweep_runs, n_list=(10, 30, 100, 300, 1000, 3000, 10000))
    sw_eta = sweep(rng_s, sweep_runs, eta_list=tuple(np.array([5, 10, 15, 20, 27, 30, 35, 40]) * DEG))
    figures = [_plot_sweep(sw_snr, "snr_db", "SNR [dB]", "sweep_snr.png", out),
                _plot_sweep(sw_n, "n", "snapshots N", "sweep_n.png", out, logx=True),
                _plot_sweep(sw_eta, "eta_deg", "η [deg]", "sweep_eta.png", out)]

    def asymptotic(r):
        return r["snr_db"] >= 10 and r["n"] >= 300 and 10 <= r["eta_deg"] <= 35

    # χ² bounds with 99 % family-wise coverage (Bonferroni over the rows that have a target)
    n_tested = 3 * sum(1 for r in sw_snr + sw_n + sw_eta if asymptotic(r))
    slo, shi = chi2_std_bounds(sweep_runs, 1.0 - 0.01 / max(n_tested, 1))
    rows_s = []
    for label, rows, key, unit in (("SNR", sw_snr, "snr_db", " dB"), ("N", sw_n, "n", ""),
                                    ("η", sw_eta, "eta_deg", "°")):
        for r in rows:
            for i in range(3):
                name = f"ML std / CRB about {AXES_W[i]}, {label} = {r[key]:g}{unit}"
                if asymptotic(r):
                    rows_s.append(summary_row(name, "-", r["std_ml"][i] / r["crb"][i],
                                              target=f"{_lit(slo)} <= ours <= {_lit(shi)}"))
                else:
                    rows_s.append(summary_row(name + " (threshold region: no target)", "-",
                                              r["std_ml"][i] / r["crb"][i]))
    return figures, summary_table(
        "Sweeps", f"ML std of the wave-frame rotation vs the CVAE CRB at (φ, θ, γ) = "
        f"(30°, 20°, 15°), base point η = 27°, SNR 10 dB, N = 1000; {sweep_runs} "
        f"runs per point; bounds lo/hi = χ² {slo:.3f}/{shi:.3f} (99 % family-wise "
        f"over {n_tested} rows)", rows_s, runs=sweep_runs)


def _fusion_table(fu: dict, fl, fusion_runs: int) -> dict:
    """The INS aided by the ML fixes against the free INS: errors, bounds and consistency."""
    late = fu["time"] > fl.fix_time[1]
    rms_f = np.sqrt(np.mean(fu["fused"][:, late] ** 2, axis=(0, 1))) / DEG
    rms_fix = np.sqrt(np.mean(fu["fix_err"] ** 2, axis=(0, 1))) / DEG
    end_f = np.sqrt(np.mean(fu["fused"][:, -1] ** 2, 0)) / DEG
    end_i = np.sqrt(np.mean(fu["ins"][:, -1] ** 2, 0)) / DEG
    max_f = np.max(np.abs(fu["fused"][:, late]), axis=(0, 1)) / DEG
    nees_r = np.sqrt(np.mean((fu["fused"][:, late] / fu["std"][:, late]) ** 2, axis=(0, 1)))
    rows_f = []
    for i, ax in enumerate(("E", "N", "U")):
        rows_f.append(summary_row(f"fused attitude RMS error ε_{ax} after the 2nd fix (< RMS of the single "
                                  "ML fixes)", "deg", rms_f[i], target=f"ours < {_lit(rms_fix[i])}"))
    for i, ax in enumerate(("E", "N", "U")):
        rows_f.append(summary_row(f"INS-only attitude error ε_{ax} at the end, RMS over runs (> the fused "
                                  "one)", "deg", end_i[i], target=f"ours > {_lit(end_f[i])}"))
    for i, ax in enumerate(("E", "N", "U")):
        rows_f.append(summary_row(f"fused max |ε_{ax}| after the 2nd fix, all runs (bounded: < 3 × the "
                                  "largest CVAE CRB σ)", "deg", max_f[i],
                                  target=f"ours < 3 * {max(SPEC_CVAE_DEG)}"))
    for i, ax in enumerate(("E", "N", "U")):
        rows_f.append(summary_row(f"fused RMS(ε_{ax} / σ_filter) (consistency)", "-", nees_r[i],
                                  target="0.7 <= ours <= 1.4"))
    return summary_table("INS fusion", "low-grade INS (gyro bias 50 deg/h, accel bias 1 mg) aided by "
                                "the 36 ML fixes in the 15-state error-state KF vs the free INS, "
                                f"{fusion_runs} runs",
                                rows_f, runs=fusion_runs)


def _notes(tol: float, runs: int) -> list[str]:
    """The notes: errata followed, what the paper prints, the geometry and the tolerances."""
    notes = [
        "§3.6 errata followed: FLU body axes (1), θ ∈ [−90°, 90°] (2), eq. (3) with the minus sign and "
        "|a_z|² (3), Stokes/Jones tilt instead of eq. (4) (4), circular-complex likelihood (5), eq. (9) with "
        "Ry(−θ′) (6), CVAE without the leading N and with components about (u, ṽ1, ṽ2) (7), line-of-sight "
        "ambiguity resolved by 'upright' (8).",
        "The seed prints no number for Fig. 2 except 'pitch worst, about 1°; heading best'; paper = 1.0 is "
        "that statement, on the pitch row (and the dashed line in Fig. 2(f)). The CVAE CRB values "
        "0.7229°/0.9360°/0.4769° are not the paper's: SPEC §3.7 computed them from the seed's eq. (7); "
        "their rows are labelled 'formula check' and carry them as 'computed', not in the paper column. "
        "Of the SPEC rows, those 3 are formula checks; the others test the estimators by Monte Carlo.",
        "Euler-angle CRBs depend on the geometry (§3.5); the CVAE bound does not. The flight puts the "
        "base ahead of the aircraft so that mid-flight (u, ṽ1, ṽ2) ≈ (nose, wing, vertical).",
        "Physics over the seed: the base's and the aircraft's geographic frames are related by the exact "
        "rotation between them instead of being taken as parallel (flat Earth, ≈ 0.1–0.3° here).",
        "The principal-eigenvector closed form is within ~1e-4 rad of the ML (first-order equivalent) and "
        "attains the CRB too; 'close to ML' (§3.7 gives no number) is taken as ≤ 1.25 × the ML ratio.",
        f"Pooled ML std tolerance ±{tol:.0%} (§3.7: ±15 % for 100 runs, ±10 % for 300; pooled "
        f"{runs}×{N_FIXES} samples).",
        "Sweep rows in the threshold region (SNR < 10 dB, N < 300, η outside [10°, 35°]) have no target.",
    ]
    return notes


def run(out_dir, runs: int | None = 60, base_seed: int = 1, console=None, sweep_runs: int | None = None,
        fusion_runs: int | None = None) -> dict:
    """Reproduce seed 002 into ``out_dir``: PNGs and ``summary.json`` (docs/conventions.md schema, written by
    :func:`aidnav.experiments.reproduce.summary.write_summary`; every ``holds`` is evaluated from its target).

    runs : Monte Carlo realisations per fix for Fig. 2 (None: 60, as in the seed); base_seed : seeds every
    random stream; sweep_runs : per sweep point (default max(200, runs)); fusion_runs : INS-fusion runs
    (default min(runs, 10)). Returns the summary dict.
    """
    study = Study(SEED, TITLE, out_dir, 60 if runs is None else runs, base_seed, console)
    runs, out = study.runs, study.out
    sweep_runs = max(200, runs) if sweep_runs is None else int(sweep_runs)
    fusion_runs = min(runs, 10) if fusion_runs is None else int(fusion_runs)
    ss = np.random.SeedSequence(base_seed).spawn(3)

    say = study.say

    # ---------------------------------------------------------------- Fig. 2
    say("seed 002: flight and geometry")
    fl = seed_flight()
    say(f"seed 002: Monte Carlo of {N_FIXES} fixes × {runs} runs (closed form, ML)")
    mc = monte_carlo_fixes(fl, runs, np.random.default_rng(ss[0]))
    figures = study.figures
    figures += _plot_fig2(mc, fl, out)
    tol = 0.10 if runs * N_FIXES >= 300 else 0.15  # §3.7: ±15 % for 100 runs, ±10 % for 300
    tables = [_fig2_table(mc, fl, runs, tol)]

    # ---------------------------------------------------------------- sweeps
    say(f"seed 002: sweeps ({sweep_runs} runs per point)")
    sweep_figures, sweep_table = _sweeps(np.random.default_rng(ss[1]), sweep_runs, out)
    figures += sweep_figures
    tables.append(sweep_table)

    # ---------------------------------------------------------------- fusion
    say(f"seed 002: INS fusion ({fusion_runs} runs)")
    fu = fusion_case(fl, fusion_runs, np.random.default_rng(ss[2]))
    figures.append(_plot_fusion(fu, out))
    tables.append(_fusion_table(fu, fl, fusion_runs))
    return study.finish(tables, _notes(tol, runs))


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main(run, SEED, 60))
