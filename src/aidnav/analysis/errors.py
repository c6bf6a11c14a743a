"""Navigation errors of an estimated trajectory against a reference, and their statistics.

Conventions (``docs/conventions.md``): errors are **estimate − reference**, evaluated at the reference's
epochs, in the local-level ENU frame at the reference position:

* position dE, dN, dU [m]: small geodetic differences turned into metres with the WGS-84 radii at
  the reference latitude (:func:`aidnav.nav.earth.lla_difference_enu`); horizontal = √(dE²+dN²),
  3D = √(dE²+dN²+dU²);
* velocity dvE, dvN, dvU [m/s];
* attitude droll, dpitch, dheading [rad] as differences of the Euler angles, each wrapped to [-π, π)
  (so heading 0.1° vs 359.9° is +0.2°). Only when both trajectories carry attitude.

Both trajectories must use the same time scale (an estimate of a GNSS-timed log is in GPS seconds of
week, docs/conventions.md "Time"); nothing is re-zeroed here. No lever arm is applied: the reference is taken
to describe the same point as the estimate (the IMU); for an antenna reference (RTKLIB ``.pos``) the
position errors include the lever arm.

Interpolation of the estimate at a reference epoch t: latitude, (unwrapped) longitude, height,
velocity and standard deviations linearly between the two bracketing estimate epochs; attitude by
quaternion slerp between the bracketing attitudes. Reference epochs are excluded — and counted in
:class:`ErrorSeries`, never dropped silently — when they lie outside the estimate's time span, when
the bracketing estimate epochs are more than ``max_dt`` apart (a gap), or when the reference position
is not finite.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from aidnav.data import Trajectory
from aidnav.nav.earth import lla_difference_enu
from aidnav.nav.rotations import attitude_error_batch, euler_to_quat_batch, quat_to_euler_batch, wrap_pi

if TYPE_CHECKING:  # pandas and scipy are imported where a table is built: the error arrays (a Monte Carlo
    import pandas as pd  # worker's evaluation) do not need them

#: ``max_dt=None`` means this many median estimate sampling intervals.
AUTO_GAP_FACTOR = 5.0

#: Statistics rows: (quantity, unit).
QUANTITIES = [
    ("pos E", "m"), ("pos N", "m"), ("pos U", "m"), ("pos horizontal", "m"), ("pos 3D", "m"),
    ("vel E", "m/s"), ("vel N", "m/s"), ("vel U", "m/s"),
    ("roll", "deg"), ("pitch", "deg"), ("heading", "deg"),
]


@dataclass
class ErrorSeries:
    """Per-epoch errors (estimate − reference) at the reference epochs that could be evaluated.

    time : (M,) reference epochs used [s], in the inputs' time scale (e.g. GPS seconds of week).
    pos : (M, 3) dE, dN, dU [m] (ENU at the reference position).
    vel : (M, 3) dvE, dvN, dvU [m/s], or None when either trajectory has no velocity.
    att : (M, 3) droll, dpitch, dheading [rad], each wrapped to [-π, π), or None when either
        trajectory has no attitude (all-NaN ``rph``, e.g. an RTK reference).
    std_pos, std_vel : (M, 3) the estimate's interpolated 1σ ENU [m], [m/s], or None.
    std_att : (M, 3) the estimate's interpolated 1σ roll, pitch, heading [rad], or None.
    n_reference : reference epochs given.
    n_outside : excluded, outside the estimate's time span.
    n_gap : excluded, inside a gap of the estimate longer than ``max_dt``.
    n_invalid : excluded, reference position not finite.
    max_dt : the gap threshold used [s].
    used : (n_reference,) bool, True where the reference epoch is in ``time``.
    notes : human-readable notes on the exclusions.
    """

    time: np.ndarray
    pos: np.ndarray
    vel: np.ndarray | None = None
    att: np.ndarray | None = None
    std_pos: np.ndarray | None = None
    std_vel: np.ndarray | None = None
    std_att: np.ndarray | None = None
    n_reference: int = 0
    n_outside: int = 0
    n_gap: int = 0
    n_invalid: int = 0
    max_dt: float = np.inf
    used: np.ndarray | None = None
    notes: list[str] = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.time)

    @property
    def n_used(self) -> int:
        """Reference epochs evaluated."""
        return len(self.time)

    @property
    def n_excluded(self) -> int:
        """Reference epochs excluded (outside span + gaps + invalid reference)."""
        return self.n_outside + self.n_gap + self.n_invalid

    @property
    def horizontal(self) -> np.ndarray:
        """Horizontal position error √(dE²+dN²) [m], (M,)."""
        return np.hypot(self.pos[:, 0], self.pos[:, 1])

    @property
    def pos3d(self) -> np.ndarray:
        """3D position error √(dE²+dN²+dU²) [m], (M,)."""
        return np.sqrt(np.sum(self.pos**2, axis=1))

    def counts(self) -> dict[str, int | float]:
        """Epoch bookkeeping as a dict (for reports and JSON)."""
        return {"reference": int(self.n_reference), "used": int(self.n_used),
                "outside_span": int(self.n_outside), "in_gaps": int(self.n_gap),
                "invalid_reference": int(self.n_invalid), "max_dt_s": float(self.max_dt)}

    def to_dataframe(self) -> pd.DataFrame:
        """Per-epoch table: ``time`` [s], errors with units in the names (angles in degrees), and the
        estimate's σ as ``<column>_std`` columns (docs/conventions.md interchange style)."""
        import pandas as pd  # lazy: pandas is heavy to import

        return pd.DataFrame(self.columns())

    def columns(self) -> dict[str, np.ndarray]:
        """The columns of :meth:`to_dataframe` as a dict of arrays."""
        cols: dict[str, np.ndarray] = {"time": self.time}
        for i, c in enumerate(("de_m", "dn_m", "du_m")):
            cols[c] = self.pos[:, i]
        cols["horizontal_m"] = self.horizontal
        cols["pos3d_m"] = self.pos3d
        if self.vel is not None:
            for i, c in enumerate(("dve_m_s", "dvn_m_s", "dvu_m_s")):
                cols[c] = self.vel[:, i]
        if self.att is not None:
            for i, c in enumerate(("droll_deg", "dpitch_deg", "dheading_deg")):
                cols[c] = np.degrees(self.att[:, i])
        if self.std_pos is not None:
            for i, c in enumerate(("de_m", "dn_m", "du_m")):
                cols["std_" + c] = self.std_pos[:, i]
        if self.std_vel is not None and self.vel is not None:
            for i, c in enumerate(("dve_m_s", "dvn_m_s", "dvu_m_s")):
                cols["std_" + c] = self.std_vel[:, i]
        if self.std_att is not None and self.att is not None:
            for i, c in enumerate(("droll_deg", "dpitch_deg", "dheading_deg")):
                cols["std_" + c] = np.degrees(self.std_att[:, i])
        return cols

    def components(self) -> dict[str, tuple[np.ndarray, np.ndarray | None, str]]:
        """Signed component errors keyed by quantity name: (error, σ or None, unit), angles in deg."""
        out: dict[str, tuple[np.ndarray, np.ndarray | None, str]] = {}
        for i, q in enumerate(("pos E", "pos N", "pos U")):
            out[q] = (self.pos[:, i], None if self.std_pos is None else self.std_pos[:, i], "m")
        if self.vel is not None:
            for i, q in enumerate(("vel E", "vel N", "vel U")):
                out[q] = (self.vel[:, i], None if self.std_vel is None else self.std_vel[:, i], "m/s")
        if self.att is not None:
            for i, q in enumerate(("roll", "pitch", "heading")):
                s = None if self.std_att is None else np.degrees(self.std_att[:, i])
                out[q] = (np.degrees(self.att[:, i]), s, "deg")
        return out


# ----------------------------------------------------------------------------------- helpers
def _has(a: np.ndarray | None) -> bool:
    return a is not None and np.size(a) > 0 and bool(np.any(np.isfinite(a)))


def _lerp(a: np.ndarray, i0: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Linear interpolation of rows of ``a`` between i0 and i0+1 with weights u ∈ [0, 1]; at u == 0
    the row i0 is returned exactly."""
    a0 = a[i0]
    i1 = np.minimum(i0 + 1, len(a) - 1)
    uu = u.reshape((-1,) + (1,) * (a.ndim - 1))
    out = a0 + uu * (a[i1] - a0)
    exact = u == 0.0
    out[exact] = a0[exact]
    return out


def _slerp(q: np.ndarray, i0: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Spherical linear interpolation of (N, 4) unit quaternions between rows i0 and i0+1."""
    q0 = q[i0]
    q1 = q[np.minimum(i0 + 1, len(q) - 1)].copy()
    d = np.sum(q0 * q1, axis=1)
    flip = d < 0  # shortest path: q and -q are the same rotation
    q1[flip] *= -1.0
    d = np.clip(np.abs(d), -1.0, 1.0)
    th = np.arccos(d)
    small = th < 1e-8
    s = np.sin(np.where(small, 1.0, th))
    w0 = np.where(small, 1.0 - u, np.sin((1.0 - u) * th) / s)
    w1 = np.where(small, u, np.sin(u * th) / s)
    out = w0[:, None] * q0 + w1[:, None] * q1
    return out / np.linalg.norm(out, axis=1, keepdims=True)


def check_time(t: np.ndarray, what: str) -> None:
    if len(t) and not np.all(np.isfinite(t)):
        raise ValueError(f"{what}: time has non-finite values")
    if len(t) > 1 and np.any(np.diff(t) <= 0):
        k = int(np.flatnonzero(np.diff(t) <= 0)[0])
        raise ValueError(f"{what}: time must be strictly increasing (t[{k}]={float(t[k])!r}, "
                         f"t[{k + 1}]={float(t[k + 1])!r})")


# ----------------------------------------------------------------------------------- errors
def trajectory_errors(est: Trajectory, ref: Trajectory, max_dt: float | None = None) -> ErrorSeries:
    """Errors of ``est`` (estimate) against ``ref`` (reference), estimate − reference.

    est, ref : :class:`~aidnav.data.Trajectory` in the same time scale [s]; lat/lon [rad], height
        [m], velocity ENU [m/s], rph [rad]. ``ref`` may lack velocity or attitude (all NaN).
    max_dt : largest spacing [s] of the two estimate epochs bracketing a reference epoch for it to be
        interpolated; a reference epoch inside a longer gap of the estimate is excluded and counted
        in ``n_gap``. ``None``: ``AUTO_GAP_FACTOR`` (5) × the estimate's median sampling interval;
        ``numpy.inf`` disables the check. A reference epoch equal to an estimate epoch is always
        used.

    Returns an :class:`ErrorSeries` (position [m] ENU, velocity [m/s], attitude [rad], the
    estimate's interpolated σ) with the counts of excluded reference epochs.
    """
    te = np.asarray(est.time, dtype=float)
    tr = np.asarray(ref.time, dtype=float)
    check_time(te, "estimate")
    check_time(tr, "reference")
    if len(te) == 0:
        raise ValueError("estimate trajectory is empty")
    if max_dt is None:
        max_dt = AUTO_GAP_FACTOR * float(np.median(np.diff(te))) if len(te) > 1 else np.inf
    present = ErrorParts(vel=_has(est.vel) and _has(ref.vel), att=_has(est.rph) and _has(ref.rph),
                         std_pos=_has(est.std_pos), std_vel=_has(est.std_vel), std_att=_has(est.std_att))
    e = errors_at(est, ref, float(max_dt), np.unwrap(np.asarray(est.lon, dtype=float)), present)
    e.notes = exclusion_notes(e.n_reference, e.n_outside, e.n_gap, e.n_invalid, float(te[0]), float(te[-1]),
                              e.max_dt)
    return e


@dataclass(frozen=True)
class ErrorParts:
    """Which parts :func:`errors_at` computes (velocity, attitude, the estimate's σ of each)."""

    vel: bool = True
    att: bool = True
    std_pos: bool = True
    std_vel: bool = True
    std_att: bool = True


def exclusion_notes(nref: int, n_out: int, n_gap: int, n_inv: int, t_first: float, t_last: float,
                    max_dt: float) -> list[str]:
    """The human-readable notes of :class:`ErrorSeries` on the excluded reference epochs."""
    notes = []
    if n_out:
        notes.append(f"{n_out} of {nref} reference epochs outside the estimate's span "
                     f"[{t_first!r}, {t_last!r}] s excluded")
    if n_gap:
        notes.append(f"{n_gap} reference epochs inside estimate gaps > {max_dt:g} s excluded")
    if n_inv:
        notes.append(f"{n_inv} reference epochs with non-finite position excluded")
    return notes


def errors_at(est: Trajectory, ref: Trajectory, max_dt: float, lon_e: np.ndarray, parts: ErrorParts
              ) -> ErrorSeries:
    """The errors of :func:`trajectory_errors` with the gap threshold ``max_dt`` [s], the estimate's
    unwrapped longitude ``lon_e`` [rad] and the ``parts`` given (no checks, no notes). A piece of the
    estimate gives the errors of the whole one at the reference epochs it brackets (the streamed
    evaluation, :mod:`aidnav.analysis.error_stream`)."""
    te = np.asarray(est.time, dtype=float)
    tr = np.asarray(ref.time, dtype=float)
    nref = len(tr)
    # bracketing estimate epoch i0 with te[i0] <= t < te[i0+1] (or t == te[-1])
    outside = (tr < te[0]) | (tr > te[-1])
    i0 = np.clip(np.searchsorted(te, tr, side="right") - 1, 0, len(te) - 1)
    on_grid = ~outside & (te[i0] == tr)
    i1 = np.minimum(i0 + 1, len(te) - 1)
    gap = ~outside & ~on_grid & ((te[i1] - te[i0]) > max_dt)
    ref_pos = np.column_stack([ref.lat, ref.lon, ref.height]).astype(float)
    invalid = ~outside & ~gap & ~np.all(np.isfinite(ref_pos), axis=1)
    used = ~(outside | gap | invalid)

    idx = i0[used]
    t = tr[used]
    den = te[np.minimum(idx + 1, len(te) - 1)] - te[idx]
    u = np.where(den > 0, (t - te[idx]) / np.where(den > 0, den, 1.0), 0.0)
    u = np.clip(u, 0.0, 1.0)
    u[te[idx] == t] = 0.0

    lat_i = _lerp(np.asarray(est.lat, dtype=float), idx, u)
    lon_i = _lerp(lon_e, idx, u)
    h_i = _lerp(np.asarray(est.height, dtype=float), idx, u)
    rl, rlon, rh = ref_pos[used, 0], ref_pos[used, 1], ref_pos[used, 2]
    de, dn, du = lla_difference_enu(lat_i, lon_i, h_i, rl, rlon, rh)
    pos = np.column_stack([de, dn, du])

    vel = None
    if parts.vel:
        vel = _lerp(np.asarray(est.vel, dtype=float).reshape(-1, 3), idx, u) \
            - np.asarray(ref.vel, dtype=float).reshape(-1, 3)[used]

    att = None
    if parts.att:
        rph_e = np.asarray(est.rph, dtype=float).reshape(-1, 3)
        ok = np.all(np.isfinite(rph_e), axis=1)
        q = np.full((len(rph_e), 4), np.nan)
        if ok.any():
            q[ok] = euler_to_quat_batch(np.ascontiguousarray(rph_e[ok]))
        rph_i = np.full((len(idx), 3), np.nan)
        if len(idx):
            interp = u > 0
            rph_i[~interp] = rph_e[idx[~interp]]  # on an estimate epoch: exact, no round trip
            if interp.any():
                ii, uu = idx[interp], u[interp]
                good = ok[ii] & ok[np.minimum(ii + 1, len(te) - 1)]
                sub = np.full((len(ii), 3), np.nan)
                if good.any():
                    qi = _slerp(q, ii[good], uu[good])
                    sub[good] = quat_to_euler_batch(np.ascontiguousarray(qi))
                rph_i[interp] = sub
        att = wrap_pi(rph_i - np.asarray(ref.rph, dtype=float).reshape(-1, 3)[used])

    def _std(a, want):
        return _lerp(np.asarray(a, dtype=float).reshape(-1, 3), idx, u) if want else None

    return ErrorSeries(time=t, pos=pos, vel=vel, att=att,
                       std_pos=_std(est.std_pos, parts.std_pos), std_vel=_std(est.std_vel, parts.std_vel),
                       std_att=_std(est.std_att, parts.std_att),
                       n_reference=nref, n_outside=int(outside.sum()), n_gap=int(gap.sum()),
                       n_invalid=int(invalid.sum()), max_dt=max_dt, used=used)


# ----------------------------------------------------------------------------------- statistics
def _select(errors: ErrorSeries, window) -> np.ndarray:
    m = np.ones(len(errors.time), dtype=bool)
    if window is not None:
        start, stop = window
        if start is not None:
            m &= errors.time >= start
        if stop is not None:
            m &= errors.time <= stop
    return m


def statistics_series(errors: ErrorSeries) -> dict[str, tuple[np.ndarray, str]]:
    """Error series per statistics row: (values, unit); angles in degrees."""
    s = {q: (e, unit) for q, (e, _, unit) in errors.components().items()}
    s["pos horizontal"] = (errors.horizontal, "m")
    s["pos 3D"] = (errors.pos3d, "m")
    return {q: s[q] for q, _ in QUANTITIES if q in s}


def error_statistics(errors: ErrorSeries, window: tuple[float | None, float | None] | None = None
                     ) -> pd.DataFrame:
    """Summary statistics of the errors, one row per quantity.

    window : optional (start, stop) [s] in the errors' time scale (inclusive; either may be None),
        e.g. to leave out the convergence phase.

    Rows (index ``quantity``): pos E, pos N, pos U, pos horizontal, pos 3D [m]; vel E/N/U [m/s]
    when velocity errors exist; roll, pitch, heading [deg] when attitude errors exist.
    Columns: ``RMS``, ``mean`` (signed), ``std`` (population, so RMS² = mean² + std²), ``p95`` (95th
    percentile of |e|), ``max`` (of |e|), ``n`` (finite samples used), ``unit``.
    Non-finite samples are left out of each row (and so of its ``n``).
    """
    m = _select(errors, window)
    rows = []
    for q, (e, unit) in statistics_series(errors).items():
        v = np.asarray(e)[m]
        rows.append(statistics_row(q, unit, v[np.isfinite(v)]))
    return statistics_frame(rows)


STAT_COLUMNS = ["quantity", "RMS", "mean", "std", "p95", "max", "n", "unit"]


def statistics_row(q: str, unit: str, v: np.ndarray) -> dict:
    """One row of :func:`error_statistics` from the finite values ``v`` of quantity ``q``."""
    n = len(v)
    if not n:
        return {"quantity": q, "RMS": np.nan, "mean": np.nan, "std": np.nan, "p95": np.nan, "max": np.nan,
                "n": 0, "unit": unit}
    a = np.abs(v)
    return {"quantity": q, "RMS": float(np.sqrt(np.mean(v * v))), "mean": float(np.mean(v)),
            "std": float(np.std(v)), "p95": float(np.percentile(a, 95)), "max": float(np.max(a)), "n": n,
            "unit": unit}


def statistics_frame(rows: list[dict]) -> pd.DataFrame:
    """The DataFrame of :func:`error_statistics` from its rows."""
    import pandas as pd  # lazy: pandas is heavy to import

    return pd.DataFrame(rows, columns=STAT_COLUMNS).set_index("quantity")


def fraction_within_sigma(errors: ErrorSeries, k: float = 1.0,
                          window: tuple[float | None, float | None] | None = None) -> pd.DataFrame:
    """Fraction of epochs with |e| ≤ k·σ (σ the estimate's own 1σ) per component.

    Rows (index ``quantity``) for the components that have both an error and a σ (pos E/N/U,
    vel E/N/U, roll/pitch/heading). Columns: ``fraction``, ``n`` (epochs with finite e and σ),
    ``expected`` = erf(k/√2), the probability for a consistent Gaussian estimator (0.683 at k=1).
    """
    m = _select(errors, window)
    fractions = {}
    for q, (e, s, _) in errors.components().items():
        if s is not None:
            a = within_flags(np.asarray(e)[m], np.asarray(s)[m], k)
            fractions[q] = (float(np.mean(a)) if a.size else np.nan, a.size)
    return within_frame(fractions, k)


def within_flags(e: np.ndarray, s: np.ndarray, k: float) -> np.ndarray:
    """|e| ≤ k·σ at the epochs where the error ``e`` and its σ ``s`` are both finite."""
    e, s = np.asarray(e), np.asarray(s)
    ok = np.isfinite(e) & np.isfinite(s)
    return np.abs(e[ok]) <= k * s[ok]


def within_frame(fractions: dict[str, tuple[float, int]], k: float) -> pd.DataFrame:
    """The DataFrame of :func:`fraction_within_sigma` from {quantity: (fraction, n)}."""
    import pandas as pd  # lazy: pandas is heavy to import
    from scipy.special import erf  # lazy: scipy.special is heavy to import

    rows = [{"quantity": q, "fraction": f, "n": int(n), "expected": float(erf(k / np.sqrt(2.0)))}
            for q, (f, n) in fractions.items()]
    return pd.DataFrame(rows, columns=["quantity", "fraction", "n", "expected"]).set_index("quantity")


def truth_index(truth_time, t, atol: float = 1e-6) -> np.ndarray:
    """Indices of the truth samples nearest to the epochs ``t`` (filter outputs of simulated data are at
    truth samples); raises ValueError when one is farther than ``atol`` [s] from every truth sample."""
    tt = np.asarray(truth_time, dtype=float)
    t = np.asarray(t, dtype=float)
    i = np.clip(np.searchsorted(tt, t), 0, len(tt) - 1)
    lo = np.clip(i - 1, 0, len(tt) - 1)
    i = np.where(np.abs(tt[lo] - t) < np.abs(tt[i] - t), lo, i)
    if np.any(np.abs(tt[i] - t) > atol):
        raise ValueError("filter output epochs are not truth samples")
    return i


def ins_error_state(res, truth: Trajectory, sensor_errors: dict | None = None, idx=None) -> np.ndarray:
    """(K, 15) error of an INS filter result against the simulation truth, in the filter's error state
    (:mod:`aidnav.filters.layout`): φ [rad] with C_est = (I − [φ×]) C_true; δv = v_est − v_true [m/s];
    δL, δλ [rad], δh [m] estimate − truth; gyro/accel bias residual = true − estimated [rad/s, m/s²]
    (what is left in the compensated measurement, the sign of the filter's bias states).

    The one "error state vs truth" of the package (experiments and seed studies build on it).
    res : a filter result with ``time``, ``state`` (N, 10: lat, lon, h, v, q) and ``bias`` (N, ≥6);
    truth : the IMU truth at the IMU samples (same time scale); sensor_errors : the ``realised`` dict
    of :func:`aidnav.sim.imu.corrupt_imu` (constant biases ``gyro_bias``, ``accel_bias``; None: the bias
    columns are NaN); idx : output indices (default: all). Raises ValueError when an output epoch is
    not a truth sample (:func:`truth_index`).
    """
    idx = np.arange(len(res.time)) if idx is None else np.asarray(idx)
    ti = truth_index(truth.time, np.asarray(res.time)[idx])
    st = res.state[idx]
    e = np.zeros((len(idx), 15))
    q_true = euler_to_quat_batch(np.ascontiguousarray(truth.rph[ti]))
    e[:, 0:3] = attitude_error_batch(np.ascontiguousarray(st[:, 6:10]), q_true)
    e[:, 3:6] = st[:, 3:6] - truth.vel[ti]
    e[:, 6] = st[:, 0] - truth.lat[ti]
    e[:, 7] = wrap_pi(st[:, 1] - truth.lon[ti])
    e[:, 8] = st[:, 2] - truth.height[ti]
    if sensor_errors is None:
        e[:, 9:15] = np.nan
    else:
        e[:, 9:12] = sensor_errors["gyro_bias"] - res.bias[idx, 0:3]
        e[:, 12:15] = sensor_errors["accel_bias"] - res.bias[idx, 3:6]
    return e
