"""``run.html``: a self-contained page of one processing run (``aidnav process`` / ``aidnav tight``).

Shows the inputs and outputs, the run's counts (fixes used / rejected / withheld, constraint updates,
timings), the outage score, the comparison with a reference, the calibration estimates, the events and
notes, the figures (embedded as data URIs) and the whole summary as JSON. Same HTML machinery and
layout rules as the campaign report (:mod:`aidnav.report.html`).

Input: the summary dict written by :func:`aidnav.apps.process.process_logs` or
:func:`aidnav.apps.tight.process_tight_files` (known keys are laid out, every other key appears in
"Other values" and in the JSON). ``summary["calibration"]`` (optional): a mapping name → value, where a
value is a number, a list of numbers, or a dict with ``value`` (number or list) and optional ``std``
(or ``sigma``) and ``unit``; a name ending in a unit (``gyro_bias_x_deg_h``) needs no ``unit``.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from aidnav.io.atomic import write_text

from .html import escape, fmt, img_file_tag, kv_table, page, table
from .maps import write_maps

__all__ = ["write_run_page", "run_page_html", "write_run_outputs", "calibration_estimates"]



def calibration_estimates(res) -> dict:
    """``summary["calibration"]`` from a filter result with ``bias`` (N, nb) and ``pdiag`` (N, n) —
    :class:`~aidnav.filters.loose.LooseResult` or :class:`~aidnav.filters.tight.TightResult`: the last
    epoch's sensor-error estimates and their 1σ = √P[9 + k, 9 + k] (error states after the 9 navigation
    states), converted to gyro bias [deg/h], accelerometer bias [µg] and scale factors [ppm]
    (names as the trajectory's bias columns, e.g. ``gyro_bias_x_deg_h``)."""
    from aidnav.filters.result import SENSOR_ERROR_UNITS, sensor_error_axis  # lazy: numba (the page: none)

    bias = np.asarray(res.bias, float)
    pdiag = np.asarray(res.pdiag, float)
    if bias.ndim != 2 or len(bias) == 0:
        return {}
    nb = min(bias.shape[1] // 3, 4) * 3  # biases and scale factors, without the misalignments:
    lay = getattr(res, "layout", None)
    if lay is not None:  # the INS block's sensor errors as the layout says (the misalignments: 27, 33 states)
        nb = int(lay[1]) - 9
    if pdiag.shape[1] < 9 + nb:
        raise ValueError(f"calibration: pdiag has {pdiag.shape[1]} states, fewer than 9 + {nb} bias states")
    out = {}
    for k in range(nb):
        name, scale = SENSOR_ERROR_UNITS[k // 3]
        var = pdiag[-1, 9 + k]
        out[name.format(sensor_error_axis(k))] = {
            "value": float(bias[-1, k] * scale),
            "std": float(math.sqrt(var) * scale) if math.isfinite(var) and var >= 0 else None}
    return out

_INPUT_KEYS = [("imu", "IMU log"), ("gnss", "GNSS fixes"), ("obs", "RINEX observations"),
               ("nav", "RINEX navigation"), ("config", "configuration"), ("output", "trajectory written"),
               ("gnss_height_offset_m", "GNSS height offset added [m]"),
               ("gnss_height_datum", "GNSS heights in the file"), ("smoothed", "smoothed (RTS)"),
               ("states", "filter states"), ("time_scale", "time scale")]
_COUNT_KEYS = [("imu_samples", "IMU samples"), ("imu_rate_hz", "IMU rate [Hz]"),
               ("gnss_fixes", "GNSS fixes"),
               ("gnss_withheld", "GNSS fixes withheld (outages)"),
               ("gnss_position_accepted", "GNSS positions accepted"),
               ("gnss_position_rejected", "GNSS positions rejected"),
               ("gnss_velocity_accepted", "GNSS velocities accepted"),
               ("gnss_velocity_rejected", "GNSS velocities rejected")]
_LAID_OUT = {k for k, _ in _INPUT_KEYS + _COUNT_KEYS} | {
    "counts", "timing_s", "outage_windows", "outage_score", "outage_score_forward", "reference",
    "calibration", "events", "notes", "warnings", "rejected_fix_times", "title", "nis", "nis_windows_far_out",
    "reinitialisations", "evaluation", "gnss_label"}


def _t(x) -> str:
    """A time [s] as written in the files (seconds of week with ms), never in e-notation."""
    try:
        return f"{float(x):.3f}"
    except (TypeError, ValueError):
        return str(x)


def _windows_table(ws: list) -> str:
    """``nis_windows_far_out``: one row per window, times readable."""
    rows = []
    for w in ws:
        band = w.get("band") or [None, None]
        rows.append([str(w.get("model", "")).replace("_", " "), _t(w.get("start")), _t(w.get("end")),
                     fmt(w.get("n")), fmt(w.get("mean_nis")), fmt(w.get("dof")),
                     f"{fmt(band[0])} – {fmt(band[1])}" if len(band) == 2 else _val(band),
                     fmt(w.get("rejected"))])
    return table(["measurement", "start [s]", "end [s]", "fixes", "mean NIS", "dof", "99.9 % band",
                  "rejected"], rows)


def _reinit_table(rs: list) -> str:
    rows = [[_t(r.get("time")), str(r.get("model", "")).replace("_", " "), str(r.get("why", "")),
             fmt(r.get("nis"))] for r in rs]
    return table(["time [s]", "measurement", "why", "NIS"], rows)


def _val(x) -> str:
    if isinstance(x, (list, tuple, np.ndarray)):
        return ", ".join(_val(v) for v in x)
    if isinstance(x, dict):
        return "; ".join(f"{k}: {_val(v)}" for k, v in x.items())
    return fmt(x)


def _json_default(x):
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, np.generic):
        return x.item()
    return str(x)


def _clean(x):
    if isinstance(x, dict):
        return {str(k): _clean(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_clean(v) for v in x]
    if isinstance(x, np.ndarray):
        return _clean(x.tolist())
    if isinstance(x, np.generic):
        x = x.item()
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x


def _unit_of(name: str) -> str:
    for suffix, unit in (("_deg_h", "deg/h"), ("_m_s2", "m/s²"), ("_m_s", "m/s"), ("_ppm", "ppm"),
                         ("_ug", "µg"), ("_mg", "mg"), ("_deg", "deg"), ("_m", "m"), ("_s", "s")):
        if name.endswith(suffix):
            return unit
    return ""


def _calibration_rows(cal) -> list[list]:
    if not isinstance(cal, dict):
        raise ValueError(f"summary['calibration'] must be a mapping name → value (got {type(cal).__name__})")
    rows = []
    for name, v in cal.items():
        if isinstance(v, dict):
            if "value" not in v:
                raise ValueError(f"summary['calibration'][{name!r}]: a dict needs a 'value' key (got "
                                 f"{sorted(v)})")
            val, std, unit = v["value"], v.get("std", v.get("sigma")), v.get("unit") or _unit_of(name)
        else:
            val, std, unit = v, None, _unit_of(name)
        rows.append([name, _val(val), "–" if std is None else _val(std), unit])
    return rows


def _score_table(o: dict) -> str:
    parts = []
    head = [["outages", fmt(o.get("n_outages"))], ["fixes withheld", fmt(o.get("n_withheld"))],
            ["fixes scored", fmt(o.get("n_scored"))],
            ["end-of-outage horizontal error, median [m]", fmt(o.get("end_error_median_m"))],
            ["end-of-outage horizontal error, 95th percentile [m]", fmt(o.get("end_error_p95_m"))],
            ["end-of-outage horizontal error, max [m]", fmt(o.get("end_error_max_m"))],
            ["RMS over the withheld fixes [m]", fmt(o.get("rms_m"))]]
    if o.get("reference"):
        head.insert(3, ["fixes scored are", str(o["reference"])])
    for q, v in (o.get("per_quality") or {}).items():
        head.append([f"RMS at quality {q} fixes [m] ({v.get('n')} fixes)", fmt(v.get("rms_m"))])
    parts.append(kv_table(head))
    per = o.get("outages") or []
    if per:
        parts.append(table(["#", "start [s]", "end [s]", "fixes", "end error [m]", "RMS [m]"],
                           [[k + 1, f"{r['start']:.3f}", f"{r['end']:.3f}", r["n"], fmt(r["end_error_m"]),
                             fmt(r["rms_m"])] for k, r in enumerate(per)]))
    return "\n".join(parts)


def run_page_html(summary: dict, figures=(), title: str | None = None) -> str:
    """The HTML text of :func:`write_run_page`."""
    if not isinstance(summary, dict):
        raise ValueError(f"summary must be a dict (got {type(summary).__name__})")
    s = summary
    if title is None:
        title = s.get("title")
    if title is None:
        inputs = [Path(str(s[k])).name for k in ("imu", "gnss", "obs") if s.get(k)]
        kind = "tight" if "obs" in s else "process"
        title = f"aidnav {kind}" + (": " + " + ".join(inputs) if inputs else "")
    parts = [f"<h1>{escape(title)}</h1>"]
    parts.append(kv_table([[label, _val(s[k])] for k, label in _INPUT_KEYS if k in s]))

    rows = [[label, _val(s[k])] for k, label in _COUNT_KEYS if k in s]
    for k, v in (s.get("counts") or {}).items():
        rows.append([k.replace("_", " "), _val(v)])
    for k, v in (s.get("timing_s") or {}).items():
        rows.append([f"time: {k} [s]", fmt(v)])
    if rows:
        parts.append("<h2>Run</h2>")
        parts.append(kv_table(rows))

    wins = s.get("outage_windows") or []
    if wins or "outage_score" in s:
        parts.append("<h2>GNSS outages</h2>")
        if wins:
            parts.append(f'<p class="note">{len(wins)} window(s), fixes withheld from the filter and used to '
                         "score it (horizontal error of the output at each withheld fix).</p>")
        for key, name in (("outage_score", "filter output"), ("outage_score_forward", "forward filter only")):
            if key in s:
                parts.append(f"<h3>Score: {name}</h3>")
                parts.append(_score_table(s[key]))

    nis = s.get("nis")
    if isinstance(nis, dict) and nis:
        parts.append("<h2>Filter consistency (NIS)</h2>")
        parts.append('<p class="note">Mean normalised innovation squared over the accepted updates against '
                     "the 95 % band of the mean of N χ²(dof) values (per-epoch values in overview.png).</p>")
        rows = []
        for name, v in nis.items():
            band = v.get("band95") or [None, None]
            ok = v.get("in_band")
            verdict = "–" if ok is None else (("in band", "good") if ok else ("OUT OF BAND", "bad"))
            rows.append([name.replace("_", " "), fmt(v.get("mean")), fmt(v.get("dof")), fmt(v.get("n")),
                         f"{fmt(band[0])} – {fmt(band[1])}", verdict])
        parts.append(table(["measurement", "mean NIS", "dof", "updates", "95 % band", "verdict"], rows))

    ws = s.get("nis_windows_far_out") or []
    if ws:
        parts.append(f"<h2>NIS windows far out of their band ({len(ws)})</h2>")
        parts.append('<p class="note">Windows where the mean NIS of the GNSS innovations is far outside '
                     "its χ² band: the σ of the fixes or of the filter is wrong there (times as in the "
                     "files).</p>")
        parts.append(_windows_table(ws))
    ri = s.get("reinitialisations") or []
    if ri:
        parts.append(f"<h2>Re-initialisations ({len(ri)})</h2>")
        parts.append(_reinit_table(ri))

    ev = s.get("evaluation")
    if isinstance(ev, dict) and ev.get("page"):
        parts.append("<h2>Evaluation against a reference</h2>")
        parts.append(f'<p><a href="{escape(str(ev["page"]))}">{escape(str(ev["page"]))}</a> '
                     f'({escape(str(ev.get("truth", "")))})</p>')

    ref = s.get("reference")
    if isinstance(ref, dict):
        parts.append("<h2>Comparison with the reference</h2>")
        parts.append(kv_table([[k.replace("_", " "), _val(v)] for k, v in ref.items()]))

    if s.get("calibration") is not None:
        parts.append("<h2>Calibration estimates</h2>")
        parts.append('<p class="note">Final estimates of the sensor-error states with their 1σ.</p>')
        parts.append(table(["quantity", "value", "1σ", "unit"], _calibration_rows(s["calibration"])))

    rej = s.get("rejected_fix_times") or []
    n_rej = s.get("gnss_position_rejected")
    if rej:
        more = f" (first {len(rej)} of {n_rej})" if isinstance(n_rej, int) and n_rej > len(rej) else ""
        parts.append(f"<h2>Rejected GNSS positions{more}</h2>")
        parts.append(f"<p><code>{escape(', '.join(f'{float(t):.3f}' for t in rej))}</code></p>")

    for key, name in (("warnings", "Warnings"), ("events", "Events"), ("notes", "Notes")):
        items = s.get(key) or []
        if items:
            parts.append(f"<h2>{name} ({len(items)})</h2>")
            parts.append('<ul class="events">' + "".join(f"<li>{escape(str(e))}</li>" for e in items)
                         + "</ul>")

    other = [[k, _val(v)] for k, v in s.items() if k not in _LAID_OUT]
    if other:
        parts.append("<h2>Other values</h2>")
        parts.append(kv_table(other))

    figs = []
    missing = []
    for f in figures or []:
        p, cap = (f if isinstance(f, (tuple, list)) else (f, None))
        p = Path(p)
        if not p.exists():
            missing.append(str(p))
            continue
        figs.append((p, cap))
    if missing:
        raise FileNotFoundError(f"run page: figure file(s) not found: {', '.join(missing)}")
    if figs:
        parts.append("<h2>Figures</h2>")
        for p, cap in figs:
            if cap:
                parts.append(f"<h3>{escape(cap)}</h3>")
            parts.append(img_file_tag(p, cap or p.stem.replace("_", " ")))

    parts.append("<h2>Summary (JSON)</h2>")
    text = json.dumps(_clean(s), indent=1, default=_json_default, allow_nan=False)
    parts.append(f"<details><summary>all values</summary><pre>{escape(text)}</pre></details>")
    parts.append('<p class="note">Generated by aidnav. Times on the input\'s time scale (GPS seconds of '
                 "week for GNSS-timed logs); positions WGS-84, errors and σ in metres ENU.</p>")
    return page(title, parts)


def write_run_page(path, summary: dict, figures=(), title: str | None = None) -> Path:
    """Write ``run.html`` of one run and return its path.

    summary : the run's summary dict (see the module docstring); figures : image files (PNG, JPEG,
    SVG) to embed, each a path or a (path, caption) pair, in order; title : page title (default from
    the inputs). Raises ``FileNotFoundError`` for a missing figure and ``ValueError`` for a malformed
    ``calibration``."""
    path = Path(path)
    text = run_page_html(summary, figures, title)
    path.parent.mkdir(parents=True, exist_ok=True)
    write_text(path, text)  # under a temporary name until complete
    return path


def write_run_outputs(out_dir, traj, gnss=None, summary: dict | None = None, records: dict | None = None,
                      figures=(), maps: bool = True, base: str = "trajectory", progress=None,
                      skeleton=None, page_summary=None, draw=None) -> dict:
    """Everything a run leaves to look at, in ``out_dir``: ``overview.png``
    (:func:`aidnav.report.overview.write_overview`), ``<base>.kml`` and ``<base>.geojson``
    (:func:`aidnav.report.maps.write_maps`, when ``maps``) and ``run.html`` embedding the overview
    and the further ``figures``. progress : optional :class:`aidnav.progress.ProgressBar` (one stage
    "figures and maps", 3 steps); skeleton : the overview's :class:`aidnav.report.overview.Skeleton`, built
    beforehand; page_summary : called once the overview and maps are written, it returns the summary of
    the page (the figure's ``summary`` completed meanwhile: ``aidnav process``'s figures' child draws the
    overview while its parent closes the trajectory file and times it); draw : how the overview is drawn
    (:func:`aidnav.report.overview.write_overview`'s ``draw``). Returns {"overview", "run_page",
    "kml", "geojson"} → paths."""
    from .overview import write_overview  # lazy: pulls in matplotlib, scipy

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    summary = summary or {}
    if progress is not None:
        progress.stage("figures and maps", total=3, unit="steps")
    paths = {"overview": write_overview(out / "overview.png", traj, gnss, summary, records,
                                        skeleton=skeleton, draw=draw)}
    if progress is not None:
        progress.advance(1)
    if maps:
        kml, gj = write_maps(out / base, traj, gnss, summary)
        paths.update(kml=kml, geojson=gj)
    if progress is not None:
        progress.advance(1)
    if page_summary is not None:
        summary = page_summary() or {}
    paths["run_page"] = write_run_page(out / "run.html", summary, [(paths["overview"], "Overview"), *figures])
    if progress is not None:
        progress.advance(1)
    return paths
