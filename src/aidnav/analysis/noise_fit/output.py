"""Outputs of a characterisation: noise.json content, the filter's ``imu:`` section and its YAML text.
"""

from __future__ import annotations

import math

import numpy as np

from aidnav.analysis.noise_fit.results import Characterisation, json_float
from aidnav.sim.imu import ImuSpec
from aidnav.units import DEG_H, DEG_H_SQRT_H, DEG_SQRT_H, M_S_SQRT_H, UG, UG_SQRT_H

# ------------------------------------------------------------------------------------------ outputs
UNIT_LABELS = {
    "gyro": {"white": ("arw_deg_sqrt_h", DEG_SQRT_H), "quantisation": ("quantisation_rad", 1.0),
             "bias_instability": ("bias_instability_deg_h", DEG_H), "gm_sigma": ("gm_sigma_deg_h", DEG_H),
             "gm_tau": ("gm_tau_s", 1.0), "rrw": ("rrw_deg_h_sqrt_h", DEG_H_SQRT_H)},
    "accel": {"white": ("vrw_m_s_sqrt_h", M_S_SQRT_H), "quantisation": ("quantisation_m_s", 1.0),
              "bias_instability": ("bias_instability_ug", UG), "gm_sigma": ("gm_sigma_ug", UG),
              "gm_tau": ("gm_tau_s", 1.0), "rrw": ("accel_rw_ug_sqrt_h", UG_SQRT_H)},
}
_ADEV_UNIT = {"gyro": ("deg_h", DEG_H), "accel": ("ug", UG)}


def noise_dict(ch: Characterisation) -> dict:
    """noise.json content: per axis, every term in the boundary units of CONVENTIONS with its status and
    95% interval, the maximum-likelihood model (all four terms, resolved or not), the ADEV table (deg/h
    for gyros, µg for accelerometers, with 95% limits and EDFs) and the notes."""
    axes = {}
    for a in ch.axes:
        units = UNIT_LABELS[a.sensor]
        d = {units[k][0]: a.terms[k].scaled(units[k][1]) for k in
             ("white", "quantisation", "bias_instability", "gm_sigma", "gm_tau", "rrw")}
        un, f = _ADEV_UNIT[a.sensor]
        q2, n2, s2, k2 = a.coef
        d["best_fit"] = {units["quantisation"][0]: math.sqrt(q2) / units["quantisation"][1],
                         units["white"][0]: math.sqrt(n2) / units["white"][1],
                         units["gm_sigma"][0]: math.sqrt(s2) / units["gm_sigma"][1],
                         "gm_tau_s": a.t_corr, units["rrw"][0]: math.sqrt(k2) / units["rrw"][1],
                         "chi2": a.deviance, "dof": a.dof, "dispersion": a.dispersion}
        d["allan"] = {"tau_s": a.taus.tolist(), f"adev_{un}": (a.adev / f).tolist(),
                      f"adev_lo_{un}": [json_float(v) for v in a.adev_lo / f],
                      f"adev_hi_{un}": [json_float(v) for v in a.adev_hi / f],
                      "edf": [json_float(v) for v in a.edf], "fitted": a.used.tolist()}
        axes[a.axis] = d
    return {
        "samples": ch.n_samples, "rate_hz": ch.fs_hz, "duration_s": ch.duration_s, "span_s": list(ch.span_s),
        "resampled": ch.resampled,
        "fit": ("white noise only: quantisation and white noise (ARW / VRW) fitted on the short-tau part; "
                "the bias instability and the random walk are not resolvable in "
                f"{ch.duration_s:.3g} s of data"
                if ch.white_only else "full model: quantisation, white noise, Gauss-Markov bias instability, "
                "random walk"),
        "warnings": ch.warnings, "vibration": ch.vibration, "static_check": ch.static,
        "conventions": {
            "units": "gyro: deg/sqrt(h), deg/h, deg/h/sqrt(h), rad; accel: m/s/sqrt(h), ug, ug/sqrt(h), m/s",
            "ci95": "95% profile-likelihood interval; each Allan variance a chi-square variable whose "
                    "degrees of freedom and correlations follow from the number of clusters and the model",
            "bias_instability": "IEEE 952 B (flicker floor ADEV = 0.6643 B) with the height of the fitted "
                                "Gauss-Markov's ADEV peak: B = 0.9294 gm_sigma, peak at tau = 1.8926 gm_tau",
            "quantisation": "IEEE 952 Q (AVAR = 3 Q^2 / tau^2); quantum = sqrt(12) Q",
            "status": "fitted (value, ci95) | not resolved (no value: lower_bound/upper_bound of its "
                      "interval; upper_bound null = unbounded)",
        },
        "axes": axes, "notes": ch.notes,
    }


def _grade_units(grade: str) -> dict:
    u = ImuSpec.grade(grade).to_units()
    return {k: (float(np.max(v)) if isinstance(v, list) else v) for k, v in u.items()}


def auto_grade(ch: Characterisation) -> str:
    """The preset (navigation, tactical, mems, consumer) whose ARW and VRW are nearest (in log) to the fit."""
    best, dist = "mems", np.inf
    arw = [a.terms["white"].value for a in ch.axes[:3] if a.terms["white"].fitted]
    vrw = [a.terms["white"].value for a in ch.axes[3:] if a.terms["white"].fitted]
    for g in ("navigation", "tactical", "mems", "consumer"):
        u = _grade_units(g)
        d = 0.0
        if arw:
            d += abs(math.log(max(arw) / DEG_SQRT_H / u["arw_deg_sqrt_h"]))
        if vrw:
            d += abs(math.log(max(vrw) / M_S_SQRT_H / u["vrw_m_s_sqrt_h"]))
        if d < dist:
            best, dist = g, d
    return best


def _fmt(x: float) -> str:
    return f"{x:.4g}"


def _fitted_max(axes, key, unit):
    """(largest fitted value [SI] or None, text listing every axis in ``unit``)."""
    vals, txt = [], []
    for a in axes:
        t = a.terms[key]
        if t.fitted:
            vals.append(t.value)
            txt.append(f"{a.axis[-1]} {_fmt(t.value / unit)} [{_fmt(t.lo / unit)}, {_fmt(t.hi / unit)}]")
        else:
            ub = "unbounded" if t.upper is None else f"< {_fmt(t.upper / unit)}"
            txt.append(f"{a.axis[-1]} not resolved ({ub})")
    return (max(vals) if vals else None), ", ".join(txt)


MERGE_HORIZON_S = 3600.0  #: horizon over which a merged bias process keeps the bias variance of GM + RW


def merge_gm_rw(sigma: float, t_corr: float, k: float,
                horizon: float = MERGE_HORIZON_S) -> tuple[float, float]:
    """One first-order Gauss-Markov (σ_eff, T_eff) for a bias that is a GM (σ, T) plus a random walk K (SI).

    The filter has one bias process per triad. The merged process keeps (i) the driving noise,
    q = 2σ²/T + K² (the bias drift over short intervals, what the filter needs between fixes), and (ii)
    the variance of the bias change over ``horizon`` [s], 2σ²(1 − e^(−H/T)) + K²H; with q fixed, the
    GM's variance over H, q·T_eff·(1 − e^(−H/T_eff)), grows with T_eff, so T_eff is found by bisection
    and σ_eff² = q·T_eff/2. Returns (σ_eff, T_eff)."""
    q = 2.0 * sigma**2 / t_corr + k**2
    want = 2.0 * sigma**2 * (-math.expm1(-horizon / t_corr)) + k**2 * horizon

    def var_h(t):
        return q * t * (-math.expm1(-horizon / t))

    lo, hi = 1e-9 * horizon, 1e9 * horizon
    for _ in range(200):
        mid = math.sqrt(lo * hi)
        if var_h(mid) < want:
            lo = mid
        else:
            hi = mid
    t_eff = math.sqrt(lo * hi)
    return math.sqrt(q * t_eff / 2.0), t_eff


def imu_section(ch: Characterisation, grade: str | None = None) -> tuple[dict, dict]:
    """The ``imu:`` section of an ``aidnav process`` configuration from a characterisation.

    One value per triad (the filter's keys are scalars): the largest fitted axis value of each noise
    density and σ (conservative) and the shortest fitted correlation time. The filter has one bias process
    per triad: when both a Gauss-Markov (σ, T) and a random walk K are fitted they are merged into one
    Gauss-Markov (:func:`merge_gm_rw`: same driving noise and same bias variance after an hour); a random
    walk alone makes a random-walk bias (tau 0). The turn-on (run-to-run)
    bias cannot be seen in one static log: its σ is the grade default, combined with the bias
    instability as √(b² + σ²) for the filter's initial bias σ. Terms the log does not resolve take the grade
    default (``grade``; None = :func:`auto_grade`), and the comment says so.

    Returns (values, comments): dicts keyed by the configuration key; comments say each value's source.
    """
    grade = grade or auto_grade(ch)
    gu = _grade_units(grade)
    vals: dict = {}
    com: dict = {}
    for g, axes in ((True, ch.axes[:3]), (False, ch.axes[3:])):
        p = "gyro" if g else "accel"
        wkey, wunit = ("arw_deg_sqrt_h", DEG_SQRT_H) if g else ("vrw_m_s_sqrt_h", M_S_SQRT_H)
        bunit, bname, bsuf = (DEG_H, "deg/h", "deg_h") if g else (UG, "ug", "ug")
        rwunit, rwsuf = (DEG_H_SQRT_H, "deg_h_sqrt_h") if g else (UG_SQRT_H, "ug_sqrt_h")
        ikey, tkey = f"{p}_bias_instability_{bsuf}", f"{p}_bias_tau_s"
        rkey, skey = f"{p}_bias_rw_{rwsuf}", f"{p}_bias_sigma_{bsuf}"

        w, wtxt = _fitted_max(axes, "white", wunit)
        wo = (f" (white noise only, from the short-tau part of {ch.duration_s:.3g} s of data)"
              if ch.white_only else "")
        if w is not None:
            vals[wkey], com[wkey] = w / wunit, f"fitted, largest axis: {wtxt}{wo}"
        else:
            vals[wkey] = gu[wkey]
            com[wkey] = f"grade default ({grade}): not resolved on any axis ({wtxt})"

        sig, stxt = _fitted_max(axes, "gm_sigma", bunit)
        tau, ttxt = _fitted_max(axes, "gm_tau", 1.0)
        taus = [a.terms["gm_tau"].value for a in axes if a.terms["gm_tau"].fitted]
        tau = min(taus) if taus else None
        kk, ktxt = _fitted_max(axes, "rrw", rwunit)
        t_def = gu[f"{p}_bias_corr_time_s"]
        if sig is not None:
            t_use = tau if tau is not None else t_def
            t_src = (f"fitted, shortest axis: {ttxt}" if tau is not None else
                     f"grade default ({grade}): the log does not resolve T ({ttxt})")
            if kk is not None:
                s_eff, t_eff = merge_gm_rw(sig, t_use, kk)
                vals[ikey] = s_eff / bunit
                com[ikey] = (f"fitted Gauss-Markov sigma {_fmt(sig / bunit)} {bname}, T {_fmt(t_use)} s "
                             f"({stxt}) merged with the fitted random walk into one Gauss-Markov (same "
                             f"driving noise, same bias variance after {MERGE_HORIZON_S:g} s)")
                vals[rkey] = kk / rwunit
                com[rkey] = (f"fitted ({ktxt}); the filter uses it only when {tkey} <= 0: here merged into "
                             "the Gauss-Markov above")
                t_use, t_src = t_eff, f"merged Gauss-Markov correlation time (fitted T: {t_src})"
            else:
                vals[ikey] = sig / bunit
                com[ikey] = f"fitted Gauss-Markov sigma, largest axis: {stxt}"
                vals[rkey] = 0.0
                com[rkey] = f"random walk not resolved ({ktxt}); unused while {tkey} > 0"
            vals[tkey], com[tkey] = t_use, t_src
        elif kk is not None:
            vals[ikey], vals[tkey], vals[rkey] = 0.0, 0.0, kk / rwunit
            com[ikey] = f"Gauss-Markov bias instability not resolved ({stxt}): the bias is a random walk"
            com[tkey] = "0: random-walk bias"
            com[rkey] = f"fitted, largest axis: {ktxt}"
        else:
            vals[ikey] = gu[f"{p}_bias_instability_{bsuf}"]
            vals[tkey] = t_def
            vals[rkey] = 0.0
            ubs = [a.terms["bias_instability"].upper for a in axes]
            bound = ("B below " + _fmt(max(ubs) / bunit) + f" {bname} (95%)") if None not in ubs else \
                "no upper bound on B"
            com[ikey] = (f"grade default ({grade}): not resolvable in {ch.duration_s:.3g} s of data (white "
                         "noise only was fitted)" if ch.white_only else
                         f"grade default ({grade}): the log is too short (or too noisy) to resolve the bias "
                         f"instability ({stxt}; {bound})")
            com[tkey] = f"grade default ({grade})" + (" (not resolvable in this log)" if ch.white_only
                                                       else "")
            com[rkey] = (f"random walk not resolvable in {ch.duration_s:.3g} s of data; unused while "
                         f"{tkey} > 0" if ch.white_only else
                         f"random walk not resolved ({ktxt}); unused while {tkey} > 0")
        tb = gu[f"{p}_bias_{bsuf}"]
        vals[skey] = math.hypot(tb, vals[ikey])
        com[skey] = (f"turn-on bias {_fmt(tb)} {bname}: grade default ({grade}), one static log cannot show "
                     "the run-to-run bias; combined with the instability above as sqrt(b^2 + sigma^2)")
    order = ["arw_deg_sqrt_h", "vrw_m_s_sqrt_h", "gyro_bias_sigma_deg_h", "accel_bias_sigma_ug",
             "gyro_bias_instability_deg_h", "accel_bias_instability_ug", "gyro_bias_tau_s",
             "accel_bias_tau_s", "gyro_bias_rw_deg_h_sqrt_h", "accel_bias_rw_ug_sqrt_h"]
    return {k: float(vals[k]) for k in order}, {k: com[k] for k in order}


def imu_yaml(ch: Characterisation, grade: str | None = None, source: str = "") -> str:
    """YAML text of the ``imu:`` section with each number's source in a comment (see :func:`imu_section`)."""
    vals, com = imu_section(ch, grade)
    head = [f"# imu: section for `aidnav process`, from `aidnav characterise` of {source or 'a static log'}",
            f"# ({ch.n_samples} samples at {ch.fs_hz:.6g} Hz, {ch.duration_s:.6g} s). Values per axis in "
            "brackets are 95% intervals.",
            "# One value per triad: the largest axis noise and sigma, the shortest correlation time."]
    if ch.white_only:
        head.append(f"# White noise only: {ch.duration_s:.3g} s of data resolve ARW / VRW; the bias "
                    "instability, its correlation time and the random walk are grade defaults (not "
                    "resolvable in this log).")
    for w in ch.warnings:
        if not w.startswith("white noise only"):
            head.append("# warning: " + w)
    lines = ["imu:"]
    for k, v in vals.items():
        lines.append(f"  {k}: {v!r}  # {com[k]}")
    return "\n".join(head + lines) + "\n"
