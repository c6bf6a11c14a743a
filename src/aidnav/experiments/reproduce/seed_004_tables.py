"""Seed 004: the seed's numbers, the case grid, and the summary tables with their verdicts (§5.3).

Every derived statistic (ratio, spread, successive ratio, T1 of the minimum) gets a Monte Carlo standard
error by resampling the runs (the same runs in every case: the common random numbers stay paired), and
every SPEC trend a margin, its signed distance from the target's boundary: a trend within 2 standard
errors of it is ``unresolved``, and a spec trend still so at the reproduction's runs is stated at its
resolution (:func:`resolved_row`: it fails, saying so). The factor-2 cells compare with the paper
(``spec`` False).
"""

from __future__ import annotations

import numpy as np

from aidnav.experiments.transfer_cases import BASE_GRADE, GRADES, LABEL, MODES  # noqa: E402, F401

from .summary import RESOLVE_SE, resolved_row, summary_row, summary_table

SWEEP_GRADES = ("high_arw", "medium_arw", "low_arw", "sub_arw")
T1_VALUES = (0, 100, 200, 300, 400, 500)
T2_VALUES = (100, 200, 400)
BASELINES = (20, 40, 60)
MASTER_TAU_S = 100.0
#: Tables 4, 5, 6 and 8 (the maneuver, T1, T2 and baseline orderings, a few percent apart) run this many times
#: the runs of the other cases (the first runs are shared: common random numbers)
TREND_RUNS_FACTOR = 3
#: the master-error models of the baseline-error study: label -> (position-drift fraction f, white velocity
#: σ [m/s] or None for the seed's 0.03 m/s, baselines [km]). The default is the white master (f = 0: truth
#: plus the POS's measurement noise, SPEC §5.1 2026-12-06); f = 0.5 (τ 300 s) is the former drifting master
MASTER_DEFAULT = "f = 0 (white master: the default), σ_v = 0.03"
MASTER_DRIFT = "f = 0.5, τ 300 s (drifting master: the former default), σ_v = 0.03"
MASTER_MODELS = {MASTER_DEFAULT: (0.0, None, BASELINES),
                 MASTER_DRIFT: (0.5, None, BASELINES),
                 "f = 0 (white position), σ_v = 0.015": (0.0, 0.015, (20, 60)),
                 "f = 0.1, σ_v = 0.015": (0.1, 0.015, (20, 60))}
#: the per-run statistics, in this order: attitude [deg], velocity [m/s], position [m], baseline [m]
QUANTS = ("heading", "pitch", "roll", "vE", "vN", "vU", "lat", "lon", "h", "baseline")
UNITS = ("deg", "deg", "deg", "m/s", "m/s", "m/s", "m", "m", "m", "m")
ATT = ("heading", "pitch", "roll")

PAPER_T4 = {"none": (0.2483, 0.0376, 0.0404), "s_turns": (0.0120, 0.0082, 0.0041),
            "o_circle": (0.0209, 0.0082, 0.0041), "figure8": (0.0116, 0.0084, 0.0040),
            "climb": (0.1521, 0.0092, 0.0038)}
PAPER_T5 = {0: (0.0116, 0.0084, 0.0040), 100: (0.0116, 0.0083, 0.0040), 200: (0.0091, 0.0085, 0.0038),
            300: (0.0093, 0.0082, 0.0038), 400: (0.0099, 0.0081, 0.0038), 500: (0.0102, 0.0082, 0.0038)}
PAPER_T6 = {100: (0.0083, 0.0076, 0.0038), 200: (0.0086, 0.0077, 0.0039), 400: (0.0091, 0.0085, 0.0038)}
PAPER_T8 = {"heading": (0.0101, 0.0098, 0.0098), "pitch": (0.0080, 0.0080, 0.0081),
            "roll": (0.0037, 0.0038, 0.0038), "vE": (0.0137, 0.0162, 0.0181), "vN": (0.0162, 0.0171, 0.0189),
            "vU": (0.0194, 0.0194, 0.0201), "lat": (0.2057, 0.2445, 0.2465), "lon": (0.1688, 0.2308, 0.2782),
            "h": (0.4942, 0.4849, 0.5192), "baseline": (0.2180, 0.5972, 1.2757)}
FACTOR2 = "paper / 2 <= ours <= 2 * paper"
N_BOOT = 400


class Group:
    """Per-run statistics of a set of cases (``{key: CaseResult}``, the same runs in each) with means and
    bootstrap standard errors of any statistic of the means."""

    def __init__(self, cases: dict):
        self.keys = list(cases)
        self.arr = np.stack([cases[k].std for k in self.keys])  # (cases, runs, quantities)
        self.runs = self.arr.shape[1]
        rng = np.random.default_rng(2026)
        self._idx = [rng.integers(0, self.runs, self.runs) for _ in range(N_BOOT)] if self.runs > 1 else []

    def means(self, idx=None) -> dict:
        a = self.arr if idx is None else self.arr[:, idx]
        m = a.mean(axis=1)
        return {k: dict(zip(QUANTS, m[i].tolist(), strict=True)) for i, k in enumerate(self.keys)}

    def stat(self, fn) -> tuple[float, float]:
        """(fn(means), its bootstrap standard error over the runs; NaN with one run)."""
        v = float(fn(self.means()))
        if not self._idx:
            return v, float("nan")
        return v, float(np.std([fn(self.means(i)) for i in self._idx], ddof=1))

    def cell_se(self, key, q) -> float:
        x = self.arr[self.keys.index(key), :, QUANTS.index(q)]
        return float(x.std(ddof=1) / np.sqrt(len(x))) if len(x) > 1 else float("nan")


def _spread(vals) -> float:
    v = np.asarray(vals, float)
    return float(np.max(np.abs(v / v.mean() - 1.0)))


def trend_row(g: Group, quantity: str, unit: str, fn, paper, target: str, dist, spec: bool = True,
              resolve: bool = True) -> dict:
    """A SPEC trend: value fn(means), target, margin = dist(value) with the bootstrap se of dist(fn).
    ``resolve`` False keeps a spec row that the runs leave within 2 standard errors ``unresolved`` (SPEC
    §5.1 decision 3 allows it for the baseline-proportionality row only)."""
    v, se = g.stat(fn)
    d, dse = g.stat(lambda m: dist(fn(m)))
    reason = None
    if not np.isfinite(dse):
        reason = "one run: no Monte Carlo standard error, the trend cannot be resolved"
    elif abs(d) < RESOLVE_SE * dse:
        need = int(np.ceil(g.runs * (RESOLVE_SE * dse / max(abs(d), 1e-300)) ** 2))
        reason = (f"the effect ({d:+.3g} from the boundary, standard error {dse:.2g}) is below what "
                  f"{g.runs} runs resolve; resolving it at 2 standard errors would need about {need} runs "
                  "per case (if the effect is what these runs estimate), beyond the reproduction's time "
                  "budget")
    row = summary_row(quantity, unit, v, paper, target, spec=spec, stderr=se, margin=(d, dse), reason=reason)
    return _resolved(row, g.runs) if resolve else row


def _resolved(row: dict, runs: int, why: str = "") -> dict:
    """A spec row still within 2 standard errors at the reproduction's runs is stated at its resolution
    (:func:`resolved_row`: it fails, saying the effect is below what the runs resolve); other rows as
    they are."""
    if row["spec"] and row["verdict"] == "unresolved":
        return resolved_row(row, runs, why or row["reason"].split("; ", 1)[-1])
    return row


def _cells(g: Group, paper: dict, names, label, suffix) -> list[dict]:
    m = g.means()
    return [summary_row(f"{q} STD, {label(k)}{suffix}", "deg" if q in ATT else UNITS[QUANTS.index(q)],
                        m[k][q], paper[k][i], FACTOR2, stderr=g.cell_se(k, q))
            for k in g.keys for i, q in enumerate(names)]


def t4_rows(g: Group, suffix: str = "", spec: bool = True) -> list[dict]:
    """Table-4 cells (factor 2) and the §5.3 Table-4 predicates."""
    rows = _cells(g, PAPER_T4, ATT, lambda m: LABEL[m], suffix)
    ph = {m: PAPER_T4[m][0] for m in MODES}
    for a, b, lim in (("none", "figure8", 5.0), ("none", "climb", 1.0), ("climb", "o_circle", 1.0),
                      ("o_circle", "s_turns", 1.0)):
        op = ">=" if lim == 5.0 else ">"
        rows.append(trend_row(g, f"heading {LABEL[a]} / {LABEL[b]}{suffix}", "-",
                              lambda m, a=a, b=b: m[a]["heading"] / m[b]["heading"], ph[a] / ph[b],
                              f"ours {op} {lim:g}", lambda v, lim=lim: v - lim, spec))
    if rows[-1]["verdict"] == "fails":  # O / S
        rows[-1]["reason"] = (rows[-1]["reason"] or "O / S not above 1") + (
            ". Our O and S leave the same heading STD on the legs (the paper's O is 1.74x S): both turn "
            "the heading far enough (360 deg, ±30 deg over 700 s) to separate the heading error from the "
            "mounting, after which the legs' STD is set by the same noise (the same draws on AB, U and CD)")
    rows.append(trend_row(g, f"heading S / 8 (S ≈ 8: within 30 %){suffix}", "-",
                          lambda m: m["s_turns"]["heading"] / m["figure8"]["heading"],
                          ph["s_turns"] / ph["figure8"], "abs(ours - 1) <= 0.3", lambda v: 0.3 - abs(v - 1),
                          spec))
    four = ("s_turns", "o_circle", "figure8", "climb")
    for k, q in ((1, "pitch"), (2, "roll")):
        pap = [PAPER_T4[m][k] for m in four]
        rows.append(trend_row(g, f"{q}: largest deviation of the 4 maneuvers from their mean{suffix}", "-",
                              lambda m, q=q: _spread([m[x][q] for x in four]), _spread(pap), "ours <= 0.3",
                              lambda v: 0.3 - v, spec))
        rows.append(trend_row(g, f"{q}: none / mean of the 4 maneuvers{suffix}", "-",
                              lambda m, q=q: m["none"][q] / np.mean([m[x][q] for x in four]),
                              PAPER_T4["none"][k] / np.mean(pap), "ours >= 2", lambda v: v - 2.0, spec))
    return rows


def _t1_low(m) -> float:
    return float(T1_VALUES[int(np.argmin([m[t]["heading"] for t in T1_VALUES]))])


def _t1_dip(m) -> float:
    """Lowest heading STD outside 100-300 s minus the lowest inside (> 0: the minimum is near 200 s)."""
    inside = [m[t]["heading"] for t in T1_VALUES if 100 <= t <= 300]
    outside = [m[t]["heading"] for t in T1_VALUES if not 100 <= t <= 300]
    return min(outside) - min(inside)


def t5_rows(g: Group, suffix: str = "", spec: bool = True) -> list[dict]:
    """Table-5 cells (factor 2) and the §5.3 Table-5 predicates."""
    rows = _cells(g, PAPER_T5, ATT, lambda t: f"T1 = {t} s", suffix)
    v = _t1_low(g.means())
    d, dse = g.stat(_t1_dip)
    reason = None
    if not np.isfinite(dse):
        reason = "one run: no Monte Carlo standard error, the position of the minimum cannot be resolved"
    elif abs(d) < RESOLVE_SE * dse:
        flat = 100 * _spread([g.means()[t]["heading"] for t in T1_VALUES])
        reason = (f"the lowest heading STD inside 100-300 s is {d:+.2g} deg below the lowest outside, "
                  f"standard error {dse:.2g}: our curve is flat within {flat:.1f} %, "
                  "the paper's dip is 22 %: the position of the minimum is not resolved by "
                  f"{g.runs} runs")
    rows.append(_resolved(summary_row(f"T1 of the lowest heading STD{suffix} (margin: lowest outside "
                                      "100-300 s − lowest inside)", "s", v, 200, "100 <= ours <= 300",
                                      spec=spec, margin=(d, dse), reason=reason), g.runs, reason or ""))
    if rows[-1]["verdict"] == "fails" and reason is None:
        flat = 100 * _spread([g.means()[t]["heading"] for t in T1_VALUES])
        rows[-1]["reason"] = (
            f"no dip: our heading STD is flat across T1 within {flat:.1f} % (the paper's dip is 22 %) and "
            f"lowest at T1 = {v:g} s ({d:+.2g} ± {dse:.2g} deg from the lowest inside 100-300 s, paired "
            "runs). The filter has converged by the end of the 900-s figure-8, and the STD over a leg "
            "removes the constant error the maneuver leaves, so no settling time shows in it")
    for k, q, tol in ((0, "heading", 0.3), (1, "pitch", 0.1), (2, "roll", 0.1)):
        rows.append(trend_row(g, f"{q}: largest deviation across T1 from the mean{suffix}", "-",
                              lambda m, q=q: _spread([m[t][q] for t in T1_VALUES]),
                              _spread([PAPER_T5[t][k] for t in T1_VALUES]), f"ours <= {tol}",
                              lambda v, tol=tol: tol - v, spec))
    return rows


def t6_rows(g: Group, suffix: str = "", spec: bool = True) -> list[dict]:
    """Table-6 cells (factor 2) and the §5.3 Table-6 predicate (heading non-decreasing with T2)."""
    rows = _cells(g, PAPER_T6, ATT, lambda t: f"T2 = {t} s", suffix)
    phs = [PAPER_T6[t][0] for t in T2_VALUES]

    def smallest(m):
        h = [m[t]["heading"] for t in T2_VALUES]
        return min(h[1] / h[0], h[2] / h[1])

    rows.append(trend_row(g, f"heading: smallest ratio of successive T2 (non-decreasing: >= 1){suffix}", "-",
                          smallest, min(phs[1] / phs[0], phs[2] / phs[1]), "ours >= 1", lambda v: v - 1.0,
                          spec))
    return rows


#: a factor whose per-run effect is below this relative size in every run does not act on the quantity (a
#: structural null: the model makes it independent of the factor, up to rounding and the filter's P0)
NULL_TOL = 1e-3


#: a first-epoch control (:func:`aidnav.experiments.reproduce.seed_004.first_epoch_control`) that reproduces
#: the near-baseline STD to this relative difference shows that the baseline acts on nothing else
CONTROL_TOL = 1e-9


def _largest_change(g: Group, q: str, keys) -> float:
    a = [g.arr[g.keys.index(k), :, QUANTS.index(q)] for k in keys]
    r = np.concatenate([a[i + 1] / a[i] for i in range(len(a) - 1)])
    return float(np.max(np.abs(r - 1.0)))


def structural_null(g: Group, q: str, keys) -> float | None:
    """The largest relative change of ``q`` between successive ``keys`` over every run when it is below
    ``NULL_TOL`` (the factor does not act on ``q`` in this model: a structural null), else None."""
    dev = _largest_change(g, q, keys)
    return dev if dev < NULL_TOL else None


def _null_reason(q: str, dev: float, control: dict | None, spec: bool = True) -> str:
    """Why the sub's ``q`` does not depend on the GNSS baseline in the white-master model (``dev``: the
    largest per-run relative change between successive L0; ``control``: the first-epoch control; a spec
    row's modelling choice and alternatives are appended by ``seed_004_verdicts._point_to_alternatives``)."""
    how = ("Velocity + attitude matching gives the sub the master's velocity error, and the white master of "
           "the seed's text has the same velocity noise (0.03 m/s) at every L0; its position noise, "
           "which does "
           "scale with L0, is not measured")
    if control is None:
        return (f"structural null: in this model the sub's {q} error does not depend on the GNSS baseline "
                f"(every run's ratios of successive L0 are within {dev:.1e} of 1; the Monte Carlo "
                "cannot move "
                f"it). {how} (it enters only the filter's P0 and the sub's first-epoch position). Modelling "
                "choice: the white master; 'Table 8, drifting master' (sensitivity) shows the growth with L0 "
                "when the master's velocity carries a baseline-dependent position drift")
    return (f"structural null: the GNSS baseline reaches the sub's {q} only through the sub's first epoch "
            "(initialised at the master's position, P0 = the master's position σ): the "
            f"{control['far']:g}-km runs restarted from the {control['near']:g}-km runs' first-epoch "
            "position "
            f"and P0 give the {control['near']:g}-km {q} STD "
            f"{'bit for bit' if control[q] == 0 else f'to {control[q]:.0e}'} in each of "
            f"{control['runs']} runs (control). {how}. What is left (every run's ratios of successive "
            "L0 within "
            f"{dev:.1e} of 1, of either sign) is the second-order coupling of that first-epoch offset "
            "(transport rate, gravity gradient), which more runs would not turn into a trend (the paper's "
            f"{q} grows by {100 * (PAPER_T8[q][2] / PAPER_T8[q][0] - 1):.0f} % from 20 to 60 km)"
            + ("" if spec else ". Modelling choice: the white master; 'Table 8, drifting master' "
               "(sensitivity) shows the growth with L0 when the master's velocity carries a "
               "baseline-dependent position drift"))


def t8_rows(g: Group, spec: bool = True, control: dict | None = None) -> list[dict]:
    """Table-8 cells (factor 2) and the §5.3 Table-8 predicates. ``control``: the first-epoch control of
    :func:`aidnav.experiments.reproduce.seed_004.first_epoch_control`: a velocity or position row whose
    control reproduces the near-baseline STD (within ``CONTROL_TOL``) is a structural null (the baseline
    acts on it through the first epoch only); without it, the ``NULL_TOL`` rule."""
    rows = []
    m = g.means()
    for q, u in zip(QUANTS, UNITS, strict=True):
        for i, b in enumerate(BASELINES):
            rows.append(summary_row(f"{q} STD, L0 = {b} km", u, m[b][q], PAPER_T8[q][i], FACTOR2,
                                    stderr=g.cell_se(b, q)))
    for q in ATT:
        rows.append(trend_row(g, f"{q}: largest deviation across L0 from the mean", "-",
                              lambda m, q=q: _spread([m[b][q] for b in BASELINES]), _spread(PAPER_T8[q]),
                              "ours <= 0.1", lambda v: 0.1 - v, spec))
    for q in ("vE", "vN", "vU", "lat", "lon"):
        p = PAPER_T8[q]
        quantity = f"{q}: smallest ratio of successive L0 (non-decreasing: >= 1)"

        def fn(m, q=q):
            return min(m[40][q] / m[20][q], m[60][q] / m[40][q])

        dev = _largest_change(g, q, BASELINES)
        by_control = control is not None and control.get(q, np.inf) <= CONTROL_TOL
        if by_control or (control is None and dev < NULL_TOL):
            rows.append(summary_row(
                quantity, "-", fn(g.means()), min(p[1] / p[0], p[2] / p[1]), "ours >= 1", spec=spec,
                margin=(0.0, 0.0), reason=_null_reason(q, dev, control if by_control else None, spec)))
        else:
            rows.append(trend_row(g, quantity, "-", fn, min(p[1] / p[0], p[2] / p[1]), "ours >= 1",
                                  lambda v: v - 1.0, spec))
    gps = {20: 0.1, 40: 0.5, 60: 1.0}
    pb = PAPER_T8["baseline"]
    reason = ("the baseline-length error is the difference of the sub's and the master's position errors. "
              "With the white master of the seed's text the master's position noise stays in it, over a "
              "floor "
              "that "
              "does not scale with the GNSS accuracy: the sub's own position error over a leg, the integral "
              "of "
              "the master's white velocity error (0.03 m/s) that velocity matching passes to it (≈ 0.24 m "
              "over "
              "a 400-s leg). Master attitude and flexure act only through the 5-m lever arm (≈ 2 mm). "
              "Modelling "
              "choice: the master's velocity noise σ_v = 0.03 m/s (the POS/AV610 figure); the 'Master-error "
              "model' sensitivity table shows the ratio with σ_v = 0.015 m/s and with the drifting master")
    ratios = {b: gps[b] / gps[20] for b in (40, 60)}

    def binding(m):  # the ratio (40/20 or 60/20 km, over the GPS ratio) nearest to leaving 0.5 … 2
        v = [m[b]["baseline"] / m[20]["baseline"] / r for b, r in ratios.items()]
        return min(v, key=lambda x: min(x - 0.5, 2.0 - x))

    pv = [pb[BASELINES.index(b)] / pb[0] / r for b, r in ratios.items()]
    # one SPEC predicate, one row (as the velocity and position rows take the smaller of their two steps)
    rows.append(trend_row(g, "baseline error: the ratio 40 / 20 or 60 / 20 km over the GPS accuracy ratio 5 "
                          "or 10 nearest to the bounds (about proportional: 0.5 … 2)", "-", binding,
                          min(pv, key=lambda x: min(x - 0.5, 2.0 - x)), "0.5 <= ours <= 2",
                          lambda v: min(v - 0.5, 2.0 - v), spec, resolve=False))
    if rows[-1]["verdict"] == "fails":
        rows[-1]["reason"] = reason
    elif rows[-1]["verdict"] == "unresolved":  # SPEC §5.1 decision 3: reported at its resolution
        rows[-1]["reason"] = (f"{rows[-1]['reason']}. SPEC §5.1 (2026-12-06, decision 3) allows this row "
                              "to stay "
                              f"unresolved when the runs cannot resolve it within the time budget. {reason}")
    for r in rows:  # the sub's horizontal position without the control: what the white master gives it
        q = r["quantity"].split(":")[0]
        if q in ("lat", "lon") and r["spec"] and r["verdict"] == "fails":
            r["reason"] += (". Physics: velocity + attitude matching does not measure position, so the "
                            f"sub's {q} error is the integral of its matched velocity error, which the white "
                            "master gives "
                            "the same at every L0; the master's position accuracy (which scales with L0) "
                            "reaches "
                            "it only through the filter's initial position covariance: the effect is a few "
                            "hundredths of a percent (the paper's is 19-65 %)")
    return rows


def master_model_rows(groups: dict) -> list[dict]:
    """The master-error study of Table 8 (a sensitivity study: no SPEC rows). For each master-error model
    (``MASTER_MODELS``: position-drift fraction f, white velocity σ_v), the baseline error's ratio 60 / 20 km
    (and 40 / 20 km) over the GPS ratio (the SPEC row's quantity) and the growth of vE and lat with L0."""
    rows = []
    gps = {20: 0.1, 40: 0.5, 60: 1.0}
    pb = PAPER_T8["baseline"]
    for label, g in groups.items():
        m = g.means()
        b = " / ".join(f"{m[x]['baseline']:.3f}" for x in g.keys)
        for x in [k for k in (40, 60) if k in g.keys]:
            r = gps[x] / gps[20]
            v, se = g.stat(lambda m, x=x, r=r: m[x]["baseline"] / m[20]["baseline"] / r)
            rows.append(summary_row(f"{label}: baseline error ratio {x} / 20 km over the GPS ratio {r:g} "
                                    f"(STD {b} m at {' / '.join(str(k) for k in g.keys)} km)", "-", v,
                                    pb[BASELINES.index(x)] / pb[0] / r, "0.5 <= ours <= 2", stderr=se,
                                    margin=(min(v - 0.5, 2.0 - v), se)))
        for q in ("vE", "lat"):
            v, se = g.stat(lambda m, q=q: m[60][q] / m[20][q])
            null = structural_null(g, q, (20, 60))
            rows.append(summary_row(f"{label}: {q} STD ratio 60 / 20 km (grows: > 1; STD at 20 km "
                                    f"{m[20][q]:.4g})", "-", v, PAPER_T8[q][2] / PAPER_T8[q][0], "ours > 1",
                                    stderr=se, margin=(v - 1.0, se) if null is None else (0.0, 0.0),
                                    reason=None if null is None else (
                                        f"structural null: every run's ratio is within {null:.1e} of 1 (the "
                                        "master's velocity noise is the same at every L0 in this model)")))
    return rows


__all__ = [
    "Group", "trend_row", "structural_null", "NULL_TOL", "CONTROL_TOL",
    "t4_rows", "t5_rows", "t6_rows", "t8_rows", "master_model_rows", "MODES", "LABEL",
    "GRADES", "BASE_GRADE", "SWEEP_GRADES", "T1_VALUES", "T2_VALUES", "BASELINES", "MASTER_TAU_S",
    "MASTER_MODELS", "MASTER_DEFAULT", "MASTER_DRIFT", "TREND_RUNS_FACTOR", "QUANTS", "UNITS", "PAPER_T4",
    "PAPER_T5", "PAPER_T6",
    "PAPER_T8", "FACTOR2", "summary_table",
]
