"""One result type of the engine filters: :class:`FilterResult`, with ``to_trajectory`` / ``to_dataframe``."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from aidnav.data import Trajectory
from aidnav.jit import njit
from aidnav.nav.earth import E2, A
from aidnav.nav.rotations import dcm_entries, dcm_from_euler, dcm_from_rotvec, euler_from_dcm, wrap_pi
from aidnav.units import ARCSEC, DEG_H, PPM, UG

from .layout import L_BARO, L_LEVER, L_MOUNT, L_NINS, L_ODO, L_TOFF, L_VDEL, MIS_PAIRS, NAV

#: the INS sensor-error states in the file units, by group of three (x, y, z): column name, factor from SI
SENSOR_ERROR_UNITS = (("gyro_bias_{}_deg_h", 1.0 / DEG_H), ("accel_bias_{}_ug", 1.0 / UG),
                      ("gyro_sf_{}_ppm", 1.0 / PPM), ("accel_sf_{}_ppm", 1.0 / PPM),
                      ("gyro_mis_{}_arcsec", 1.0 / ARCSEC), ("gyro_mis_{}_arcsec", 1.0 / ARCSEC),
                      ("accel_mis_{}_arcsec", 1.0 / ARCSEC), ("accel_mis_{}_arcsec", 1.0 / ARCSEC))


def sensor_error_axis(k: int) -> str:
    """Axis label of sensor-error state k (0-based after the navigation block): x, y, z per triad; the
    misalignments' pair (out, in) from k = 12 on (gyro 12–17, accelerometer 18–23)."""
    return MIS_PAIRS[(k - 12) % 6] if k >= 12 else "xyz"[k % 3]


@dataclass
class FilterResult:
    """Output of an engine filter (arrays in aidnav conventions).

    ``state`` (N, 10): lat, lon [rad], h [m], v^n ENU [m/s], q_b^n; ``bias`` (N, n − 9): the sensor and
    calibration estimates in layout order (gyro bias [rad/s], accel bias [m/s²], scale factors [-],
    odometer scale factor [-], barometer bias [m], …); ``pdiag`` (N, n): covariance diagonal (forward,
    or smoothed when ``smoothed``); ``innovations``: the engine's innovation log (time, model id and
    name, status 1/0/−1, nis, innovation and diag S (rows), record index); ``records``: the per-GNSS-fix
    view of it (``pos_status``, ``pos_nis``, ``pos_innov`` …); ``layout``: the index table of
    :mod:`aidnav.filters.layout` and ``state_names`` one name per error state.
    """

    time: np.ndarray
    state: np.ndarray
    bias: np.ndarray
    pdiag: np.ndarray
    node_time: np.ndarray
    records: dict = field(default_factory=dict)
    counts: dict = field(default_factory=dict)
    smoothed: bool = False
    final_P: np.ndarray | None = None
    forward_state: np.ndarray | None = None
    forward_pdiag: np.ndarray | None = None
    cov_time: np.ndarray | None = None  # (K,) sample times of ``cov`` (only with ``cov_times``)
    cov: np.ndarray | None = None  # (K, n, n) forward covariance at ``cov_time``
    innovations: dict = field(default_factory=dict)
    events: list = field(default_factory=list)
    layout: np.ndarray | None = None
    state_names: list = field(default_factory=list)
    calibration_base: dict = field(default_factory=dict)  # configured values the calibration corrects
    gnss_time: np.ndarray | None = None  # (M,) times of the GNSS fixes that ``records`` are indexed by

    @property
    def calibration(self) -> dict:
        """:func:`calibration_summary` of this result."""
        return calibration_summary(self)

    def to_trajectory(self):
        """:class:`aidnav.data.Trajectory` with σ, bias and calibration columns."""
        return to_trajectory(self)

    def to_dataframe(self):
        """pandas DataFrame: time, navigation state, sensor/calibration estimates and 1σ of every error
        state (``sigma_<name>``, in the state's unit: rad, m/s, rad/rad/m for δL δλ δh, …)."""
        import pandas as pd  # lazy: pandas is heavy to import

        s = self.state
        cols = {"time_s": self.time, "lat_rad": s[:, 0], "lon_rad": s[:, 1], "height_m": s[:, 2],
                "vel_e_m_s": s[:, 3], "vel_n_m_s": s[:, 4], "vel_u_m_s": s[:, 5]}
        for i in range(4):
            cols[f"q{i}"] = s[:, 6 + i]
        names = self.state_names or [f"x{i}" for i in range(self.pdiag.shape[1])]
        for j in range(self.bias.shape[1]):
            if NAV + j < len(names):
                cols[names[NAV + j]] = self.bias[:, j]
        sig = np.sqrt(np.maximum(self.pdiag, 0.0))
        for j, nm in enumerate(names):
            cols[f"sigma_{nm}"] = sig[:, j]
        return pd.DataFrame(cols)


LooseResult = FilterResult


def calibration_summary(result, base: dict | None = None) -> dict:
    """The self-calibration of a loose-filter result as ``{name: {"value", "std", "estimated"}}``
    (docs/conventions.md "Command outputs"), at the last output epoch:

    * ``time_offset_s`` [s], added to the IMU stamps (configured value + estimate);
    * ``lever_arm_m`` IMU → GNSS antenna, body RFU [m] (3 values / 3 σ);
    * ``mounting_rph_deg`` IMU body → vehicle as roll, pitch, heading [deg] (C_b^v = C(r, p, h), as the
      NHC uses it); their
      σ from the rotation-vector σ's through the Jacobian of the angles (cross-covariances neglected);
    * ``odometer_scale`` [-] (s = (1 + k) v);
    * ``gnss_velocity_delay_s`` [s] (only when estimated): the GNSS velocity describes its stamp − τ.

    A quantity whose state is not in the layout is reported with its configured value, ``std`` None
    and ``estimated`` False. ``base``: the configured values (default ``result.calibration_base``; the
    caller adds an offset it applied to the stamps itself, e.g. ``aidnav process``'s
    ``imu.time_offset_s``, by passing ``{"time_offset_s": ...}``).
    """
    b = dict(getattr(result, "calibration_base", None) or {})
    b.update(base or {})
    lay = getattr(result, "layout", None)
    bias = np.asarray(result.bias, float)
    pdiag = np.asarray(result.pdiag, float)

    def est(slot, width):
        if lay is None or lay[slot] < 0 or len(bias) == 0:
            return None, None
        i = int(lay[slot])
        return bias[-1, i - NAV:i - NAV + width], np.sqrt(np.maximum(pdiag[-1, i:i + width], 0.0))

    out = {}
    t0 = float(b.get("time_offset_s", 0.0))
    v, s = est(L_TOFF, 1)
    out["time_offset_s"] = {"value": t0, "std": None, "estimated": False}
    if v is not None:
        out["time_offset_s"] = {"value": t0 + float(v[0]), "std": float(s[0]), "estimated": True}
    l0 = np.asarray(b.get("lever_arm_m", (0.0, 0.0, 0.0)), float)
    v, s = est(L_LEVER, 3)
    out["lever_arm_m"] = {"value": [float(x) for x in l0], "std": None, "estimated": False}
    if v is not None:
        out["lever_arm_m"] = {"value": [float(x) for x in l0 + v], "std": [float(x) for x in s],
                              "estimated": True}
    m0 = np.asarray(b.get("mounting_rph_deg", (0.0, 0.0, 0.0)), float)
    v, s = est(L_MOUNT, 3)
    if v is None:
        out["mounting_rph_deg"] = {"value": [float(x) for x in m0], "std": None, "estimated": False}
    else:
        r = np.radians(m0)
        cbv = dcm_from_euler(r[0], r[1], r[2])  # the C_b^v the NHC and odometer use (loose._models)

        def rph_of(rho):
            c_hat = dcm_from_rotvec(-np.asarray(rho, float)) @ cbv
            return np.asarray(euler_from_dcm(np.ascontiguousarray(c_hat)), float)

        rph = rph_of(v)
        # σ of roll, pitch, heading: J diag(σ_ρ²) Jᵀ with J = ∂(r, p, h)/∂ρ by central differences
        J = np.empty((3, 3))
        for j in range(3):
            e = np.zeros(3)
            e[j] = 1e-6
            J[:, j] = wrap_pi(rph_of(v + e) - rph_of(v - e)) / 2e-6
        sd = np.sqrt(np.diag(J @ np.diag(np.asarray(s, float) ** 2) @ J.T))
        rph = np.degrees(rph)
        rph[2] %= 360.0
        out["mounting_rph_deg"] = {"value": [float(x) for x in rph],
                                   "std": [float(x) for x in np.degrees(sd)], "estimated": True}
    v, s = est(L_VDEL, 1)
    if v is not None:  # only where estimated (not one of the convention's names)
        out["gnss_velocity_delay_s"] = {"value": float(v[0]), "std": float(s[0]), "estimated": True}
    v, s = est(L_ODO, 1)
    k0 = float(b.get("odometer_scale", 0.0))
    out["odometer_scale"] = {"value": k0, "std": None, "estimated": False}
    if v is not None:
        out["odometer_scale"] = {"value": k0 + float(v[0]), "std": float(s[0]), "estimated": True}
    return out


def to_trajectory(res: FilterResult):
    """FilterResult → :class:`aidnav.data.Trajectory` with σ columns and bias columns (one pass of
    :func:`_trajectory_arrays` over the rows)."""
    s = np.ascontiguousarray(res.state, dtype=np.float64)
    pdiag = np.ascontiguousarray(res.pdiag, dtype=np.float64)
    bias = np.ascontiguousarray(res.bias, dtype=np.float64)
    names, cols, scales = [], [], []
    lay = getattr(res, "layout", None)
    n_groups = res.bias.shape[1] // 3 if lay is None else (int(lay[L_NINS]) - NAV) // 3
    for j in range(n_groups):
        for i in range(3):
            name, scale = SENSOR_ERROR_UNITS[j]
            names.append(name.format(sensor_error_axis(3 * j + i)))
            cols.append(3 * j + i), scales.append(scale)
    if lay is not None:
        if lay[L_ODO] >= 0:
            names.append("odometer_scale_ppm"), cols.append(int(lay[L_ODO]) - NAV), scales.append(1e6)
        if lay[L_BARO] >= 0:
            names.append("baro_bias_m"), cols.append(int(lay[L_BARO]) - NAV), scales.append(1.0)
    N = len(s)
    if s.shape[1] < 10 or pdiag.shape[1] < 9 or len(pdiag) != N or len(bias) != N:
        raise ValueError("to_trajectory: state (N, 10), pdiag (N, >= 9) and bias (N, ·) expected")
    if cols and max(cols) >= bias.shape[1]:
        raise ValueError("to_trajectory: the layout names bias columns the result does not have")
    rph, std_pos, std_vel, std_att = (np.empty((N, 3)) for _ in range(4))
    extra = np.empty((len(names), N))
    _trajectory_arrays(s, pdiag, bias, np.array(cols, np.int64), np.array(scales, np.float64), rph, std_pos,
                       std_vel, std_att, extra)
    return Trajectory(time=res.time, lat=s[:, 0], lon=s[:, 1], height=s[:, 2], vel=s[:, 3:6], rph=rph,
                      std_pos=std_pos, std_vel=std_vel, std_att=std_att,
                      extra={k: extra[j] for j, k in enumerate(names)})


@njit(cache=True, nogil=True)
def _trajectory_arrays(st, pdiag, bias, cols, scales, rph, std_pos, std_vel, std_att, extra):
    """The columns of :func:`to_trajectory` row by row, into the arrays given: σ = √max(P_ii, 0) (NaN
    stays NaN); std_pos E, N, U [m] from σ δλ, δL, δh with R_N, R_M (:func:`aidnav.nav.earth.radii`);
    roll/pitch/heading of the quaternion (:func:`aidnav.nav.rotations.euler_from_dcm`); φ (E, N, U) →
    roll/pitch/heading σ (diagonal approximation about the current heading); ``extra[j]`` the bias
    column ``cols[j]`` × ``scales[j]``. The operations of the former whole-array version, in its order
    (the same numbers)."""
    c = np.empty((3, 3))
    p = np.empty(9)
    for k in range(st.shape[0]):
        for i in range(9):
            v = pdiag[k, i]
            p[i] = np.sqrt(v if (v > 0.0 or np.isnan(v)) else 0.0)  # np.maximum(v, 0.0) (−0 → 0)
        lat, h = st[k, 0], st[k, 2]
        sl = np.sin(lat)
        w2 = 1.0 - E2 * sl * sl
        w = np.sqrt(w2)
        rn = A / w
        rm = A * (1.0 - E2) / (w2 * w)
        std_pos[k, 0] = p[7] * (rn + h) * np.cos(lat)
        std_pos[k, 1] = p[6] * (rm + h)
        std_pos[k, 2] = p[8]
        c[0, 0], c[0, 1], c[0, 2], c[1, 0], c[1, 1], c[1, 2], c[2, 0], c[2, 1], c[2, 2] = dcm_entries(
            st[k, 6], st[k, 7], st[k, 8], st[k, 9])
        r, pt, hd = euler_from_dcm(c)
        rph[k, 0], rph[k, 1], rph[k, 2] = r, pt, hd
        ch, sh = np.cos(hd), np.sin(hd)
        a, b = ch * p[1], sh * p[0]
        std_att[k, 0] = np.sqrt(a * a + b * b)
        a, b = sh * p[1], ch * p[0]
        std_att[k, 1] = np.sqrt(a * a + b * b)
        std_att[k, 2] = p[2]
        for i in range(3):
            std_vel[k, i] = p[3 + i]
        for j in range(cols.shape[0]):
            extra[j, k] = bias[k, cols[j]] * scales[j]


def nis_health(result, window_s: float = 30.0, far_ratio: float = 2.0) -> dict:
    """Windows where the GNSS innovations say the filter is wrong (issue 26): for GNSS position and
    velocity, over consecutive windows of ``window_s`` seconds, the mean NIS of every fix that was tested
    (accepted or rejected) against the two-sided 99.9 % band of the mean of N χ²(dof) values (normal
    approximation, dof ± 3.29 √(2 dof / N)). A window is *far out of band* when it is outside that band
    and its mean is more than ``far_ratio`` × dof (σ too small) or less than dof / ``far_ratio``² (σ too
    large). Returns {"windows": [{"model", "start", "end", "n", "mean_nis", "dof", "band", "rejected"}],
    "warnings": [text]} — the lead puts the warnings into the summary."""
    rec = getattr(result, "records", None) or {}
    t_fix = getattr(result, "gnss_time", None)
    out = {"windows": [], "warnings": []}
    if t_fix is None:
        return out
    for name, st, nis, inn in (("gnss_position", "pos_status", "pos_nis", "pos_innov"),
                               ("gnss_velocity", "vel_status", "vel_nis", "vel_innov")):
        if st not in rec:
            continue
        tested = (rec[st] >= 0) & np.isfinite(rec[nis])
        if not tested.any():
            continue
        t = np.asarray(t_fix)[tested]
        v = rec[nis][tested]
        dof_k = np.isfinite(rec[inn][tested]).sum(axis=1).astype(float)
        rej = rec[st][tested] == 0
        edges = np.arange(t[0], t[-1] + window_s, window_s)
        for a in edges:
            m = (t >= a) & (t < a + window_s)
            n = int(m.sum())
            if n < 5:
                continue
            dof = float(dof_k[m].mean())
            mean = float(v[m].mean())
            half = 3.29 * np.sqrt(2.0 * dof / n)
            outside = not (dof - half <= mean <= dof + half)
            far = outside and (mean > far_ratio * dof or mean < dof / far_ratio ** 2)
            if far:
                out["windows"].append({"model": name, "start": float(a), "end": float(a + window_s), "n": n,
                                       "mean_nis": mean, "dof": dof, "band": [dof - half, dof + half],
                                       "rejected": int(rej[m].sum())})
        ws = [w for w in out["windows"] if w["model"] == name]
        if ws:
            worst = max(ws, key=lambda w: abs(np.log(w["mean_nis"] / w["dof"])))
            out["warnings"].append(
                f"{name}: mean NIS far out of its chi-square band in {len(ws)} window(s) of {window_s:g} s "
                f"(worst {worst['mean_nis']:.1f} vs {worst['dof']:.0f} dof at t={worst['start']:.1f}): the "
                + ("filter's sigma is too small there (noise model or a calibration is wrong)"
                   if worst["mean_nis"] > worst["dof"] else "filter's sigma is too large there"))
    return out


def summary_calibration(result, base: dict | None = None) -> dict:
    """``summary["calibration"]`` of a loose-filter result: the INS sensor errors at the last epoch
    (``gyro_bias_x_deg_h`` …, ``accel_bias_x_ug`` …, scale factors ``…_ppm``, read through the layout so
    that calibration states are never mistaken for scale factors) as {"value", "std", "estimated"}, then
    :func:`calibration_summary` (``time_offset_s``, ``lever_arm_m``, ``mounting_rph_deg``,
    ``odometer_scale``, …)."""
    lay = getattr(result, "layout", None)
    bias = np.asarray(result.bias, float)
    pdiag = np.asarray(result.pdiag, float)
    out = {}
    if len(bias):
        nins = int(lay[L_NINS]) if lay is not None else NAV + 6
        for k in range(nins - NAV):
            name, scale = SENSOR_ERROR_UNITS[k // 3]
            var = pdiag[-1, NAV + k]
            out[name.format(sensor_error_axis(k))] = {"value": float(bias[-1, k] * scale),
                                           "std": float(np.sqrt(var) * scale) if var >= 0 else None,
                                           "estimated": True}
    out.update(calibration_summary(result, base))
    return out
