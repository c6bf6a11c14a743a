"""Map exports of a trajectory: KML (Google Earth; written as text) and GeoJSON (QGIS, web maps).

Layers (KML folders; GeoJSON features with a ``layer`` property):

* ``trajectory`` — the track as line pieces, coloured by the horizontal 1σ √(σE² + σN²) [m] of the
  solution (fixed classes, :data:`SIGMA_CLASSES_M`) or by the GNSS solution quality (RTKLIB Q, when the
  trajectory has a ``quality`` column, e.g. a ``.pos`` reference);
* ``gnss`` — the GNSS fixes (points), coloured by quality Q when the fixes have it, else by their σ;
  withheld fixes (inside an outage) are flagged;
* ``rejected`` — the fixes the filter rejected (points, red);
* ``outage`` — the track during each GNSS outage window (lines), with the window's start/end times.

* ``track`` (KML) — the same trajectory as one timed ``gx:Track`` (a ``when`` per point), so Google
  Earth's time slider replays it; GeoJSON gives each piece and fix its times instead.

Coordinates: WGS-84 longitude, latitude [deg] and height [m], written with Python's shortest round-trip
float text (``repr``), so they read back to the same double (far below the 1e-9° tested). GeoJSON follows
RFC 7946 ([lon, lat, height], height ellipsoidal). KML geometries use ``altitudeMode`` **absolute**
(a flight is drawn at its altitude, not clamped to the ground); KML's absolute altitude is above mean sea
level, so with ``geoid_undulation_m`` N (the configured datum offset of a log whose heights were above
MSL) the KML altitude is h − N, else the ellipsoidal height is written and the description says so.

Times: where the GPS week is known, ISO 8601 UTC (``2025-07-08T19:34:18.499000Z``; leap seconds from
:mod:`aidnav.io.gpstime`): KML ``TimeStamp``/``TimeSpan``/``gx:Track`` ``when``; GeoJSON properties
``time``/``time_start``/``time_end`` beside ``gps_week`` and the seconds of week (``time_s``,
``time_start_s``, ``time_end_s``). Styles are shared (one per colour class, referenced by ``styleUrl``),
not written per point. Long tracks are decimated to at most ``max_points`` points (every k-th sample
plus the last); epochs with a non-finite position are left out of the lines and counted in the document
description.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from aidnav.data import GnssData, Trajectory
from aidnav.io.atomic import replacing
from aidnav.io.gpstime import week_sow_to_utc_iso
from aidnav.nav.plain import wrap_pi  # numpy: the figures' child runs without numba

__all__ = ["write_kml", "write_geojson", "write_maps", "SIGMA_CLASSES_M", "QUALITY_NAMES", "track_pieces"]

#: Upper bounds [m] of the horizontal-σ colour classes (the last class is "above the last bound").
SIGMA_CLASSES_M = (0.05, 0.2, 1.0, 5.0, 20.0)
#: Colours (#rrggbb) of the σ classes, good (green) to poor (dark red), plus "no σ" (grey).
_SIGMA_COLOURS = ("#1a9850", "#91cf60", "#d9ef8b", "#fee08b", "#fc8d59", "#b2182b")
_NO_SIGMA = "#3366cc"
#: RTKLIB solution quality flags and their usual colours.
QUALITY_NAMES = {1: "fix", 2: "float", 3: "SBAS", 4: "DGPS", 5: "single", 6: "PPP", 0: "unknown"}
_QUALITY_COLOURS = {1: "#1a9850", 2: "#fee08b", 3: "#66c2a5", 4: "#3288bd", 5: "#d73027", 6: "#9e0142",
                    0: "#888888"}
_OUTAGE_COLOUR = "#ff7f00"
_REJECTED_COLOUR = "#e41a1c"


def _deg(lat, lon) -> tuple[np.ndarray, np.ndarray]:
    lon = wrap_pi(np.asarray(lon, float))
    return np.degrees(np.asarray(lat, float)), np.degrees(lon)


def _sigma_class(sig_h: np.ndarray) -> np.ndarray:
    """Class index per epoch (0 … len(SIGMA_CLASSES_M)); -1 for a non-finite σ."""
    c = np.searchsorted(np.asarray(SIGMA_CLASSES_M), sig_h, side="left")
    return np.where(np.isfinite(sig_h), c, -1)


def _sigma_label(c: int) -> str:
    if c < 0:
        return "σh unknown"
    b = SIGMA_CLASSES_M
    if c == 0:
        return f"σh ≤ {b[0]:g} m"
    if c >= len(b):
        return f"σh > {b[-1]:g} m"
    return f"{b[c - 1]:g} < σh ≤ {b[c]:g} m"


def _quality_of(traj_or_gnss) -> np.ndarray | None:
    q = getattr(traj_or_gnss, "quality", None)
    if q is None and isinstance(traj_or_gnss, Trajectory):
        q = traj_or_gnss.extra.get("quality")
    return None if q is None else np.asarray(q).astype(int)


def _classes(obj, color_by: str) -> tuple[np.ndarray, str]:
    """Per-epoch class ids and the colouring used ("quality" / "sigma" / "none")."""
    n = len(obj.time)
    if color_by not in ("auto", "sigma", "quality"):
        raise ValueError(f"color_by must be 'auto', 'sigma' or 'quality' (got {color_by!r})")
    q = _quality_of(obj)
    if color_by == "quality" and q is None:
        raise ValueError("color_by='quality': the data have no quality column")
    if q is not None and color_by in ("quality", "auto"):
        return q, "quality"
    sp = obj.std_pos
    if sp is None:
        if color_by == "sigma" and isinstance(obj, Trajectory):
            raise ValueError("color_by='sigma': the trajectory has no position σ (std_pos)")
        return np.full(n, -1), "none"
    return _sigma_class(np.hypot(sp[:, 0], sp[:, 1])), "sigma"


def _colour(c: int, mode: str) -> str:
    if mode == "quality":
        return _QUALITY_COLOURS.get(int(c), "#888888")
    if mode == "sigma" and c >= 0:
        return _SIGMA_COLOURS[min(int(c), len(_SIGMA_COLOURS) - 1)]
    return _NO_SIGMA


def _label(c: int, mode: str) -> str:
    if mode == "quality":
        return f"Q={int(c)} ({QUALITY_NAMES.get(int(c), '?')})"
    return _sigma_label(int(c)) if mode == "sigma" else "track"


def _decimate(n: int, max_points: int) -> np.ndarray:
    if max_points < 2:
        raise ValueError("max_points must be >= 2")
    step = max(1, math.ceil(n / max_points))
    idx = np.arange(0, n, step)
    if n and idx[-1] != n - 1:
        idx = np.append(idx, n - 1)
    return idx


def track_pieces(traj: Trajectory, color_by: str = "auto", max_points: int = 20000):
    """The trajectory as line pieces of one colour class each.

    Returns (pieces, mode, n_dropped): pieces is a list of dicts {cls, colour, label, idx (indices into
    ``traj``), t0, t1}; consecutive pieces share their boundary epoch so the drawn line is continuous;
    a non-finite position splits the line. mode: "sigma", "quality" or "none"; n_dropped: epochs left
    out for a non-finite position."""
    n = len(traj.time)
    cls, mode = _classes(traj, color_by)
    ok = np.isfinite(traj.lat) & np.isfinite(traj.lon) & np.isfinite(traj.height)
    n_dropped = int((~ok).sum())
    idx = _decimate(n, max_points) if n else np.zeros(0, int)
    idx = idx[ok[idx]]
    out = []
    if len(idx) == 0:
        return out, mode, n_dropped
    bad = np.concatenate([[0], np.cumsum(~ok)])  # bad[i] = non-finite epochs before i
    gap = bad[idx[1:]] - bad[idx[:-1] + 1] > 0  # a non-finite epoch between consecutive points
    ci = cls[idx]
    change = ci[1:] != ci[:-1]
    brk = np.flatnonzero(gap | change)  # a piece ends after point j
    start = 0
    bounds = []
    for j in brk:
        bounds.append((start, j + 1 if (change[j] and not gap[j]) else j))  # inclusive end
        start = j + 1
    bounds.append((start, len(idx) - 1))
    for k, (s, e) in enumerate(bounds):
        if e == s:  # one point: drawn as the end of the previous piece, or isolated between gaps
            shared = k > 0 and bounds[k - 1][1] == s
            if not shared:
                n_dropped += 1
            continue
        ii = idx[s:e + 1]
        c = int(ci[s])
        out.append({"cls": c, "colour": _colour(c, mode), "label": _label(c, mode), "idx": ii,
                    "t0": float(traj.time[ii[0]]), "t1": float(traj.time[ii[-1]])})
    return out, mode, n_dropped


def fix_groups(gnss: GnssData, rejected_times, outages) -> tuple[np.ndarray, np.ndarray]:
    """Masks (rejected, withheld) over the fixes."""
    t = np.asarray(gnss.time, float)
    rej = np.zeros(len(t), bool)
    if rejected_times is not None and len(rejected_times):
        rt = np.sort(np.asarray(rejected_times, float))
        k = np.clip(np.searchsorted(rt, t), 1, max(len(rt) - 1, 1))
        near = np.minimum(np.abs(rt[k - 1] - t), np.abs(rt[np.minimum(k, len(rt) - 1)] - t))
        rej = near <= 1e-6
    wh = np.zeros(len(t), bool)
    for a, b in outages or []:
        wh |= (t >= a) & (t < b)
    return rej, wh


def _outage_idx(traj: Trajectory, a: float, b: float, max_points: int) -> np.ndarray:
    m = np.flatnonzero((traj.time >= a) & (traj.time < b) & np.isfinite(traj.lat) & np.isfinite(traj.lon))
    if len(m) > max_points:
        m = m[_decimate(len(m), max_points)]
    return m


def _coords(traj_or_gnss, idx, dh: float = 0.0) -> list[tuple[float, float, float]]:
    la, lo = _deg(traj_or_gnss.lat[idx], traj_or_gnss.lon[idx])
    h = np.asarray(traj_or_gnss.height, float)[idx] - dh
    return [(float(x), float(y), float(z) if math.isfinite(z) else 0.0) for x, y, z in zip(lo, la, h,
                                                                                            strict=True)]


def _iso(week, t) -> list[str] | None:
    """ISO 8601 UTC strings of the seconds of week ``t`` (None when the week is unknown)."""
    if week is None:
        return None
    return [str(x) for x in np.atleast_1d(week_sow_to_utc_iso(int(week), np.asarray(t, float)))]


def _fix_text(g: GnssData, i: int, rejected: bool, withheld: bool, week=None) -> dict:
    p = {"time_s": float(g.time[i])}
    if week is not None:
        p["time"] = _iso(week, [g.time[i]])[0]
        p["gps_week"] = int(week)
    if g.quality is not None:
        q = int(g.quality[i])
        p["quality"] = q
        p["quality_name"] = QUALITY_NAMES.get(q, "?")
    if g.std_pos is not None:
        s = g.std_pos[i]
        p["std_e_m"], p["std_n_m"], p["std_u_m"] = (float(x) if math.isfinite(x) else None for x in s)
    p["rejected"] = bool(rejected)
    p["withheld"] = bool(withheld)
    return p


def _kml_colour(hex_rgb: str, alpha: int = 255) -> str:
    """KML's colour text (aabbggrr) of ``#rrggbb``."""
    return f"{alpha:02x}{hex_rgb[5:7]}{hex_rgb[3:5]}{hex_rgb[1:3]}".lower()


_ICON = "http://maps.google.com/mapfiles/kml/shapes/placemark_circle.png"


def _kml_coords(coords) -> str:
    return " ".join(f"{x!r},{y!r},{z!r}" for x, y, z in coords)


def _kml_time(when: str | None = None, span: tuple[str, str] | None = None) -> str:
    if when is not None:
        return f"<TimeStamp><when>{when}</when></TimeStamp>"
    if span is not None:
        return f"<TimeSpan><begin>{span[0]}</begin><end>{span[1]}</end></TimeSpan>"
    return ""


def _kml_placemark(geometry: str, coords, style: str, name: str | None = None,
                   description: str | None = None, when: str | None = None,
                   span: tuple[str, str] | None = None) -> str:
    """A placemark with an absolute-altitude geometry (issue 38) and its UTC time stamp or span."""
    parts = ["<Placemark>"]
    if name is not None:
        parts.append(f"<name>{_xml(name)}</name>")
    if description is not None:
        parts.append(f"<description>{_xml(description)}</description>")
    parts.append(_kml_time(when, span))
    parts.append(f"<styleUrl>#{style}</styleUrl><{geometry}><altitudeMode>absolute</altitudeMode>"
                 f"<coordinates>{_kml_coords(coords)}</coordinates></{geometry}></Placemark>")
    return "".join(parts)


def _xml(text: str) -> str:
    return text.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")


def _week(traj: Trajectory, gnss: GnssData | None):
    w = getattr(traj, "week", None)
    return w if w is not None else (gnss.week if gnss is not None else None)


def write_kml(path, traj: Trajectory, gnss: GnssData | None = None, outages=None, rejected_times=None,
              color_by: str = "auto", max_points: int = 20000, max_fixes: int = 20000,
              name: str | None = None, geoid_undulation_m: float | None = None) -> Path:
    """Write a KML file of ``traj`` (folders ``trajectory``, ``track``, ``gnss``, ``rejected``,
    ``outage``; see the module docstring) and return its path.

    gnss : GNSS fixes (optional); outages : [(start, end)] windows [s, on the trajectory's time scale],
    e.g. ``summary["outage_windows"]``; rejected_times : times [s] of the fixes the filter rejected
    (``summary["rejected_fix_times"]``), matched to the fixes within 1 µs; color_by : "auto" (quality
    when present, else σ), "sigma" or "quality"; max_points / max_fixes : decimation limits;
    geoid_undulation_m : N [m] (ellipsoidal − MSL) so that the absolute altitudes are above MSL.

    Written as text (issue 41): one style per colour in the document, referenced by the placemarks (no
    style per point), ids numbered in the document (the same inputs give the same bytes). Geometries
    with ``altitudeMode`` absolute, UTC time stamps/spans and a timed ``gx:Track`` (issue 38).
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    dh = float(geoid_undulation_m or 0.0)
    week = _week(traj, gnss)
    pieces, mode, n_drop = track_pieces(traj, color_by, max_points)
    desc = [f"{len(traj.time)} epochs, {sum(len(p['idx']) for p in pieces)} points drawn, coloured by "
            f"{mode}",
            "altitudes absolute: " + (f"ellipsoidal height − geoid undulation {dh:+.3f} m (above MSL)" if dh
                                      else "WGS-84 ellipsoidal heights (the geoid undulation is not known "
                                      "here: Google Earth reads them as above MSL)"),
            "times UTC" if week is not None else "no GPS week: no time stamps"]
    if n_drop:
        desc.append(f"{n_drop} epochs without a finite position left out")
    styles: dict[tuple[str, str], str] = {}  # (kind, colour) -> id

    def style(kind: str, colour: str) -> str:
        return styles.setdefault((kind, colour), f"{kind}{len(styles)}")

    def span(t0: float, t1: float):
        return None if week is None else tuple(_iso(week, [t0, t1]))

    body = ["<Folder><name>trajectory</name>"]
    for k, p in enumerate(pieces):
        text = f"piece {k}: {p['label']}, t = {p['t0']:.3f} … {p['t1']:.3f} s"
        body.append(_kml_placemark("LineString", _coords(traj, p["idx"], dh), style("line", p["colour"]),
                                   p["label"], text, span=span(p["t0"], p["t1"])))
    body.append("</Folder>")
    if week is not None:  # one timed track for Google Earth's time slider
        ii = np.flatnonzero(np.isfinite(traj.lat) & np.isfinite(traj.lon) & np.isfinite(traj.height))
        ii = ii[_decimate(len(ii), max_points)] if len(ii) else ii
        if len(ii) >= 2:
            whens = "".join(f"<when>{w}</when>" for w in _iso(week, traj.time[ii]))
            gxc = "".join(f"<gx:coord>{x!r} {y!r} {z!r}</gx:coord>" for x, y, z in _coords(traj, ii, dh))
            body += ["<Folder><name>track</name><Placemark><name>trajectory (timed)</name>"
                     f"<styleUrl>#{style('line', _NO_SIGMA)}</styleUrl><gx:Track><altitudeMode>absolute"
                     f"</altitudeMode>{whens}{gxc}</gx:Track></Placemark></Folder>"]
    fixes = _kml_fixes(gnss, rejected_times, outages, color_by, max_fixes, desc, dh)
    if fixes is not None:  # the points' styles in the order of the fixes (the ids: the same bytes as before)
        for colour in fixes[1]:
            style("point", colour)
    tail = ["<Folder><name>outage</name>"]
    for k, (a, b) in enumerate(outages or []):
        ii = _outage_idx(traj, a, b, max_points)
        if len(ii) < 2:
            continue
        tail.append(_kml_placemark("LineString", _coords(traj, ii, dh), style("outage", _OUTAGE_COLOUR),
                                   f"outage {k + 1}", f"GNSS outage {a:.3f} – {b:.3f} s ({b - a:g} s)",
                                   span=span(a, b)))
    tail.append("</Folder>")
    head = ['<?xml version="1.0" encoding="UTF-8"?>\n<kml xmlns="http://www.opengis.net/kml/2.2" '
            'xmlns:gx="http://www.google.com/kml/ext/2.2">',
            f"<Document><name>{_xml(name or path.stem)}</name>",
            f"<description>{_xml('; '.join(desc))}</description>"]
    for (kind, colour), sid in styles.items():
        if kind == "point":
            head.append(f'<Style id="{sid}"><IconStyle><color>{_kml_colour(colour)}</color><scale>0.5</scale>'
                        f"<Icon><href>{_ICON}</href></Icon></IconStyle><LabelStyle><scale>0</scale>"
                        "</LabelStyle></Style>")
        else:
            head.append(f'<Style id="{sid}"><LineStyle><color>{_kml_colour(colour)}</color>'
                        f"<width>{6 if kind == 'outage' else 3}</width></LineStyle></Style>")
    # written a placemark at a time (memory bounded by the decimated track, not by the fixes: issue 41),
    # under a temporary name until complete
    with replacing(path) as tmp, open(tmp, "w", encoding="utf-8") as f:
        f.write("\n".join(head + body))
        if fixes is not None:
            for folder, rejected in (("gnss", False), ("rejected", True)):
                f.write(f"\n<Folder><name>{folder}</name>")
                for line in _kml_fix_placemarks(gnss, fixes, rejected, week, style):
                    f.write("\n" + line)
                f.write("\n</Folder>")
        f.write("\n" + "\n".join(tail + ["</Document></kml>"]) + "\n")
    return path


def _kml_fixes(gnss, rejected_times, outages, color_by: str, max_fixes: int, desc: list, dh: float):
    """(indices of the fixes drawn, their colours, their coordinates (lon, lat [deg], altitude [m] with
    ``dh`` removed), rejected flags, withheld flags) of a KML file, or None without fixes; a decimation is
    said in ``desc``."""
    if gnss is None or not len(gnss):
        return None
    rej, wh = fix_groups(gnss, rejected_times, outages)
    cls, gmode = _classes(gnss, color_by if color_by != "quality" or gnss.quality is not None else "auto")
    sel = np.flatnonzero(np.isfinite(gnss.lat) & np.isfinite(gnss.lon))
    if len(sel) > max_fixes:
        desc.append(f"GNSS fixes decimated from {len(sel)} to at most {max_fixes}")
        keep = sel[_decimate(len(sel), max_fixes)]
        sel = np.union1d(keep, sel[rej[sel]])  # every rejected fix is kept
    colours = [_REJECTED_COLOUR if rej[i] else ("#bbbbbb" if wh[i] else _colour(cls[i], gmode)) for i in sel]
    return sel, colours, _coords(gnss, sel, dh), rej, wh


def _kml_fix_placemarks(gnss, fixes, rejected: bool, week, style):
    """The Point placemarks of the drawn fixes that are (not) ``rejected``, one at a time."""
    sel, colours, coords, rej, wh = fixes
    for i, colour, c in zip(sel, colours, coords, strict=True):
        if bool(rej[i]) != rejected:
            continue
        info = _fix_text(gnss, int(i), rej[i], wh[i], week)
        yield _kml_placemark("Point", [c], style("point", colour),
                             description=json.dumps(info), when=info.get("time"))


def _feature(geom_type: str, coords, props: dict) -> dict:
    return {"type": "Feature", "geometry": {"type": geom_type, "coordinates": coords}, "properties": props}


def _geojson_parts(traj: Trajectory, gnss: GnssData | None, outages, rejected_times, color_by: str,
                   max_points: int, max_fixes: int):
    """(the features, one at a time; the collection's properties) of :func:`geojson_dict`."""
    week = _week(traj, gnss)

    def times(t0, t1, stem="time"):
        if week is None:
            return {}
        a, b = _iso(week, [t0, t1])
        return {f"{stem}_start": a, f"{stem}_end": b, "gps_week": int(week)}

    pieces, mode, n_drop = track_pieces(traj, color_by, max_points)

    def features():
        for p in pieces:
            props = {"layer": "trajectory", "class": p["label"], "color_by": mode, "stroke": p["colour"],
                     "stroke-width": 3, **times(p["t0"], p["t1"]), "time_start_s": p["t0"],
                     "time_end_s": p["t1"]}
            yield _feature("LineString", [list(c) for c in _coords(traj, p["idx"])], props)
        if gnss is not None and len(gnss):
            rej, wh = fix_groups(gnss, rejected_times, outages)
            cls, gmode = _classes(gnss, color_by if color_by != "quality" or gnss.quality is not None
                                  else "auto")
            sel = np.flatnonzero(np.isfinite(gnss.lat) & np.isfinite(gnss.lon))
            if len(sel) > max_fixes:
                sel = np.union1d(sel[_decimate(len(sel), max_fixes)], sel[rej[sel]])
            for i, c in zip(sel, _coords(gnss, sel), strict=True):
                colour = _REJECTED_COLOUR if rej[i] else ("#bbbbbb" if wh[i] else _colour(cls[i], gmode))
                props = {"layer": "rejected" if rej[i] else "gnss", "marker-color": colour,
                         "marker-size": "small", **_fix_text(gnss, int(i), rej[i], wh[i], week)}
                yield _feature("Point", list(c), props)
        for k, (a, b) in enumerate(outages or []):
            ii = _outage_idx(traj, a, b, max_points)
            if len(ii) < 2:
                continue
            props = {"layer": "outage", "outage": k + 1, **times(a, b), "start_s": float(a),
                     "end_s": float(b), "length_s": float(b - a), "stroke": _OUTAGE_COLOUR, "stroke-width": 6}
            yield _feature("LineString", [list(c) for c in _coords(traj, ii)], props)

    props = {"epochs": len(traj.time), "non_finite_epochs_left_out": n_drop, "color_by": mode,
             "sigma_classes_m": list(SIGMA_CLASSES_M), "height": "WGS-84 ellipsoidal [m]",
             "times": ("ISO 8601 UTC (time*, from GPS week + seconds of week *_s)"
                       if week is not None else "seconds (*_s); GPS week unknown")}
    return features(), props


def geojson_dict(traj: Trajectory, gnss: GnssData | None = None, outages=None, rejected_times=None,
                 color_by: str = "auto", max_points: int = 20000, max_fixes: int = 20000) -> dict:
    """The GeoJSON FeatureCollection (a dict) written by :func:`write_geojson`."""
    feats, props = _geojson_parts(traj, gnss, outages, rejected_times, color_by, max_points, max_fixes)
    return {"type": "FeatureCollection", "features": list(feats), "properties": props}


def write_geojson(path, traj: Trajectory, gnss: GnssData | None = None, outages=None, rejected_times=None,
                  color_by: str = "auto", max_points: int = 20000, max_fixes: int = 20000) -> Path:
    """Write a GeoJSON FeatureCollection of ``traj`` (features tagged ``layer`` = trajectory / gnss /
    rejected / outage; arguments as :func:`write_kml`) and return its path. Colours follow the
    simplestyle properties (``stroke``, ``marker-color``) understood by most web viewers.

    Written a feature at a time (the bytes of ``json.dumps(geojson_dict(...))``; memory bounded by the
    decimated track, not by the fixes: issue 41), under a temporary name until complete."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    feats, props = _geojson_parts(traj, gnss, outages, rejected_times, color_by, max_points, max_fixes)
    with replacing(path) as tmp, open(tmp, "w", encoding="utf-8") as f:
        f.write('{"type": "FeatureCollection", "features": [')
        for k, feat in enumerate(feats):
            f.write((", " if k else "") + json.dumps(feat, allow_nan=False))
        f.write('], "properties": ' + json.dumps(props, allow_nan=False) + "}\n")
    return path


def write_maps(base, traj: Trajectory, gnss: GnssData | None = None, summary: dict | None = None,
               kml: bool = True, geojson: bool = True, **kw) -> list[Path]:
    """``base.kml`` and/or ``base.geojson`` (``base`` without suffix, e.g. ``OUT/trajectory``), with the
    outage windows and rejected fix times of an ``aidnav process`` summary when given. Returns the
    paths written."""
    base = Path(base)
    summary = summary or {}
    outages = [tuple(w) for w in summary.get("outage_windows", [])]
    rejected = summary.get("rejected_fix_times")
    out = []
    if kml:
        if "geoid_undulation_m" not in kw and summary.get("gnss_height_offset_m"):
            # the configured datum offset of a log above MSL is its geoid undulation N: KML altitude h − N
            kw_kml = {**kw, "geoid_undulation_m": float(summary["gnss_height_offset_m"])}
        else:
            kw_kml = kw
        out.append(write_kml(base.with_suffix(".kml"), traj, gnss, outages, rejected, **kw_kml))
    if geojson:
        out.append(write_geojson(base.with_suffix(".geojson"), traj, gnss, outages, rejected, **kw))
    return out
