"""Simulated GNSS outages of ``aidnav process``: parse, windows, the fixes withheld, scores.

Outages are given in seconds after the first GNSS epoch: ``START:LENGTH[:PERIOD]``; with a period they
repeat while the whole outage fits before the last GNSS epoch. Withheld fixes are kept aside and scored
(horizontal error of the output, interpolated to each withheld epoch, against the withheld fix; fixes
with quality Q = 1 only when the file has a quality column).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from aidnav.data import GnssData
from aidnav.errors import InputError


@dataclass
class Outage:
    start_s: float
    length_s: float
    period_s: float | None = None


def parse_outage(text: str) -> Outage:
    """``START:LENGTH[:PERIOD]`` in seconds → :class:`Outage` (clear error on bad text)."""
    parts = text.split(":")
    try:
        vals = [float(p) for p in parts]
    except ValueError:
        raise InputError(f"--outage {text!r}: expected START:LENGTH[:PERIOD] in seconds") from None
    if (len(vals) not in (2, 3) or not np.isfinite(vals).all() or vals[0] < 0 or vals[1] <= 0
            or (len(vals) == 3 and vals[2] <= vals[1])):
        raise InputError(f"--outage {text!r}: expected START:LENGTH[:PERIOD] with START >= 0, LENGTH > 0 "
                         "and PERIOD > LENGTH")
    return Outage(vals[0], vals[1], vals[2] if len(vals) == 3 else None)


def outage_windows(outages: list[Outage], t_first: float, t_last: float) -> list[tuple[float, float]]:
    """Absolute [start, end) windows of the outages (repeated ones while they fit before t_last).

    An outage that does not fit inside the GNSS span is an error (it would withhold nothing)."""
    wins = []
    for o in outages:
        s = t_first + o.start_s
        if s + o.length_s > t_last + 1e-9:
            raise InputError(f"--outage {o.start_s:g}:{o.length_s:g}: ends {s + o.length_s - t_first:.1f} s "
                             f"after the first fix but the GNSS fixes span only {t_last - t_first:.1f} s")
        while s + o.length_s <= t_last + 1e-9:
            wins.append((s, s + o.length_s))
            if not o.period_s:
                break
            s += o.period_s
    return wins


def scored_fixes(gnss: GnssData, withheld) -> np.ndarray:
    """The withheld fixes an outage is scored on: those of quality 1 (RTK fixed) when any withheld fix
    has it, else all withheld fixes (a log without RTK fixes, e.g. a ROS bag: GBAS → Q 4)."""
    good = withheld.copy()
    if gnss.quality is not None and (withheld & (gnss.quality == 1)).any():
        good &= gnss.quality == 1
    return good


def outage_errors(traj, gnss: GnssData, withheld, after: float = -np.inf):
    """(times, horizontal errors) of the output, interpolated to the withheld fixes of
    :func:`scored_fixes` inside its span and after ``after``."""
    from aidnav.nav.earth import lla_difference_enu  # lazy: pulls in numba

    good = scored_fixes(gnss, withheld)
    t = gnss.time[good]
    inside = (t >= traj.time[0]) & (t <= traj.time[-1]) & (t > after)
    t = t[inside]
    if len(t) == 0:
        return t, np.zeros(0)
    lat = np.interp(t, traj.time, traj.lat)
    lon = np.interp(t, traj.time, np.unwrap(traj.lon))
    de, dn, _ = lla_difference_enu(lat, lon, 0.0, gnss.lat[good][inside], gnss.lon[good][inside], 0.0)
    return t, np.hypot(de, dn)


def withheld_coverage(traj, gnss: GnssData, withheld) -> float:
    """Share of the withheld fixes of quality 1 inside the output's span whose east and north errors are
    both within 3σ of the output's σ (both interpolated to the fix): issue 35's coverage on a real log;
    NaN where no such fix (no quality column, or none withheld inside the span)."""
    from aidnav.nav.earth import lla_difference_enu  # lazy: pulls in numba

    if gnss.quality is None:
        return float("nan")
    ok = withheld & (gnss.quality == 1) & (gnss.time > traj.time[0]) & (gnss.time < traj.time[-1])
    if not ok.any():
        return float("nan")
    t = gnss.time[ok]
    lat, lon = np.interp(t, traj.time, traj.lat), np.interp(t, traj.time, traj.lon)
    e, n, _ = lla_difference_enu(lat, lon, 0.0, gnss.lat[ok], gnss.lon[ok], 0.0)
    se, sn = np.interp(t, traj.time, traj.std_pos[:, 0]), np.interp(t, traj.time, traj.std_pos[:, 1])
    return float(np.mean((np.abs(e) <= 3 * se) & (np.abs(n) <= 3 * sn)))


def score_outages(traj, gnss: GnssData, wins, withheld) -> dict:
    """Horizontal errors at the withheld fixes: end-of-outage statistics and RMS over all of them."""
    return outage_score(*outage_errors(traj, gnss, withheld), wins, withheld, gnss)


def outage_score(t, herr, wins, withheld, gnss: GnssData | None = None) -> dict:
    """:func:`score_outages` from the errors at the withheld fixes (:func:`outage_errors`); with ``gnss``
    the fixes scored are named (``reference``) and, where the file has qualities, the RMS per quality."""
    ref = {}
    if gnss is not None:
        q1 = gnss.quality is not None and bool((withheld & (gnss.quality == 1)).any())
        ref["reference"] = ("the withheld fixes of quality 1, RTK fixed" if q1 else
                            "all withheld fixes, none being of quality 1")
    if len(t) == 0:
        return {"n_withheld": int(withheld.sum()), "n_scored": 0, **ref}
    if gnss is not None and gnss.quality is not None:
        idx = np.clip(np.searchsorted(gnss.time, t), 0, len(gnss.time) - 1)
        q = np.asarray(gnss.quality)[idx]
        ref["per_quality"] = {str(int(k)): {"n": int((q == k).sum()),
                                            "rms_m": float(np.sqrt(np.mean(herr[q == k] ** 2)))}
                              for k in np.unique(q)}
    ends = []
    per = []
    for a, b in wins:
        m = (t >= a) & (t < b)
        if m.any():
            ends.append(float(herr[m][-1]))
            per.append({"start": a, "end": b, "n": int(m.sum()), "end_error_m": float(herr[m][-1]),
                        "rms_m": float(np.sqrt(np.mean(herr[m] ** 2)))})
    ends = np.array(ends)
    return {
        "n_outages": len(wins), "n_withheld": int(withheld.sum()), "n_scored": int(len(herr)),
        "end_error_median_m": float(np.median(ends)) if len(ends) else None,
        "end_error_p95_m": float(np.percentile(ends, 95)) if len(ends) else None,
        "end_error_max_m": float(ends.max()) if len(ends) else None,
        "rms_m": float(np.sqrt(np.mean(herr**2))),
        "outages": per,
        **ref,
    }


def first_updates(result, wins) -> list[float]:
    """Per outage window [a, b): the output time (the forward result's stamps) of the first GNSS update
    after it — the first fix tagged ≥ b whose position or velocity was accepted (``result.records``) is
    applied at the first sample whose IMU time reaches its tag − the online time-offset estimate (the
    engine's due time), i.e. the first output row i with ``time[i] − d̂_final ≥ tag − d̂[i − 1]``
    (``loose.loose_result`` stamps every output with the final estimate d̂_final); NaN where no update
    follows. Without a time-offset state the update's time is its tag."""
    from aidnav.filters.layout import NAV  # lazy: the filter layer only where a result is scored

    tg = np.asarray(result.gnss_time, float)
    rec = result.records
    used = (np.asarray(rec.get("pos_status", np.full(len(tg), -1))) == 1) | \
        (np.asarray(rec.get("vel_status", np.full(len(tg), -1))) == 1)
    t = np.asarray(result.time, float)
    if "time_offset" in result.state_names:
        d = np.asarray(result.bias[:, result.state_names.index("time_offset") - NAV], float)
        d_prev = np.concatenate([[d[0]], d[:-1]])
        u, due_shift = t - d[-1], d_prev
    else:
        u, due_shift = t, np.zeros_like(t)
    out = []
    for _, b in wins:
        j = np.flatnonzero(used & (tg >= b))
        if not len(j):
            out.append(float("nan"))
            continue
        i = np.flatnonzero(u >= tg[j[0]] - due_shift)
        out.append(float(t[i[0]]) if len(i) else float("nan"))
    return out


def outage_end_errors(traj, gnss: GnssData, withheld, wins, t_update=None) -> np.ndarray:
    """End-of-outage horizontal error of each outage with a scored fix (the drive README's protocol: the
    error at the last withheld epoch, what the outage did before GNSS returns): the output interpolated to
    its last scored withheld fix against that fix; where that fix falls at or after the outage's first
    update (``t_update``, :func:`first_updates`, output times), the **last output before that update**
    against the scored fixes interpolated to that output's time (the one owner of this score)."""
    from aidnav.nav.earth import lla_difference_enu  # lazy: pulls in numba

    t, herr = outage_errors(traj, gnss, withheld)
    good = scored_fixes(gnss, withheld)
    tg, lat_g, lon_g = gnss.time[good], gnss.lat[good], np.unwrap(gnss.lon[good])
    ends = []
    for w, (a, b) in enumerate(wins):
        m = np.flatnonzero((t >= a) & (t < b))
        if not len(m):
            continue
        tu = np.nan if t_update is None else t_update[w]
        if not (np.isfinite(tu) and t[m[-1]] >= tu):
            ends.append(float(herr[m[-1]]))
            continue
        i = int(np.searchsorted(traj.time, tu)) - 1  # the last output strictly before the update
        to = traj.time[i]
        de, dn, _ = lla_difference_enu(traj.lat[i:i + 1], traj.lon[i:i + 1], 0.0,
                                       np.interp([to], tg, lat_g), np.interp([to], tg, lon_g), 0.0)
        ends.append(float(np.hypot(de[0], dn[0])))
    return np.array(ends)


def run_outage_ends(run) -> np.ndarray:
    """:func:`outage_end_errors` of a :class:`aidnav.apps.process_stream.ProcessRun` kept whole (``keep``):
    its forward output scored with :func:`first_updates` of its result; a smoothed output (every fix in
    it) is scored at the last withheld fixes as they are."""
    res = run.result
    fwd = res is not None and not res.smoothed and res.gnss_time is not None and len(res.time) > 1
    return outage_end_errors(run.trajectory, run.gnss, run.withheld, run.windows,
                             first_updates(res, run.windows) if fwd else None)


def withheld_fixes(gnss: GnssData, wins) -> np.ndarray:
    """The fixes inside the outage windows ``wins`` ([start, end) each): not given to the filter."""
    withheld = np.zeros(len(gnss), bool)
    for a, b in wins:
        withheld |= (gnss.time >= a) & (gnss.time < b)
    return withheld
