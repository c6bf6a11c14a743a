"""``aidnav process``: read IMU + GNSS logs, run the loosely coupled filter (and smoother), score
simulated outages, write the trajectory and a summary.

Times stay on the input's scale (GPS seconds of week for GNSS-timed logs). Outages are given in
seconds after the first GNSS epoch: ``START:LENGTH[:PERIOD]``; with a period they repeat while the
whole outage fits before the last GNSS epoch. Withheld fixes are kept aside and scored (horizontal
error of the output, interpolated to each withheld epoch, against the withheld fix; fixes with
quality Q = 1 only when the file has a quality column).
"""

from __future__ import annotations

import json
import time as _time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from aidnav.data import GnssData, ImuData
from aidnav.filters.config import LooseConfig
from aidnav.io.errors import DataError


class ConfigError(ValueError):
    """A configuration file that does not validate; the message names the key."""


def load_config(path) -> LooseConfig:
    """Read a YAML configuration of the loosely coupled filter (unknown keys are errors)."""
    from pydantic import ValidationError

    path = Path(path)
    try:
        data = yaml.safe_load(path.read_text()) or {}
    except (OSError, yaml.YAMLError) as e:
        raise ConfigError(f"{path}: cannot read configuration: {e}") from e
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: expected a mapping at the top level")
    try:
        return LooseConfig.model_validate(data)
    except ValidationError as e:
        lines = []
        for err in e.errors():
            key = ".".join(str(p) for p in err["loc"])
            lines.append(f"{key}: {err['msg']}")
        raise ConfigError(f"{path}: invalid configuration:\n  " + "\n  ".join(lines)) from None


def read_imu_any(path, time_offset_s: float = 0.0) -> ImuData:
    """IMU log by format: interchange CSV/Parquet, or a raw rtklibexplorer CSV (no header) + .tag."""
    path = Path(path)
    if not path.exists():
        raise DataError(path, None, "file not found")
    if path.suffix.lower() in (".parquet", ".pq"):
        from aidnav.io.interchange import read_imu

        return read_imu(path)
    with open(path, "rb") as f:
        head = f.read(4096).decode("utf-8", "replace")
    first = next((ln for ln in head.splitlines() if ln.strip() and not ln.startswith("#")), "")
    if not first:
        raise DataError(path, 1, "empty file")
    if "time" in first:
        from aidnav.io.interchange import read_imu

        return read_imu(path)
    from aidnav.io.logs import read_rtklibexplorer_imu

    return read_rtklibexplorer_imu(path)


def read_gnss_any(path, height_offset_m: float = 0.0) -> GnssData:
    """GNSS fixes: RTKLIB ``.pos`` or interchange CSV/Parquet."""
    path = Path(path)
    if not path.exists():
        raise DataError(path, None, "file not found")
    if path.suffix.lower() == ".pos":
        from aidnav.io.rtklib import read_pos

        return read_pos(path, height_offset_m=height_offset_m)
    from aidnav.io.interchange import read_gnss

    g = read_gnss(path)
    if height_offset_m:
        g.height = g.height + height_offset_m
    return g


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
        raise ValueError(f"--outage {text!r}: expected START:LENGTH[:PERIOD] in seconds") from None
    if len(vals) not in (2, 3) or vals[1] <= 0 or (len(vals) == 3 and vals[2] <= vals[1]):
        raise ValueError(f"--outage {text!r}: expected START:LENGTH[:PERIOD] with LENGTH > 0 and "
                         "PERIOD > LENGTH")
    return Outage(vals[0], vals[1], vals[2] if len(vals) == 3 else None)


def outage_windows(outages: list[Outage], t_first: float, t_last: float) -> list[tuple[float, float]]:
    """Absolute [start, end) windows of the outages (repeated ones while they fit before t_last)."""
    wins = []
    for o in outages:
        s = t_first + o.start_s
        while s + o.length_s <= t_last + 1e-9:
            wins.append((s, s + o.length_s))
            if not o.period_s:
                break
            s += o.period_s
    return wins


def score_outages(traj, gnss: GnssData, wins, withheld) -> dict:
    """Horizontal errors at the withheld fixes: end-of-outage statistics and RMS over all of them."""
    from aidnav.nav.earth import lla_difference_enu

    good = withheld.copy()
    if gnss.quality is not None:
        good &= gnss.quality == 1
    t = gnss.time[good]
    inside = (t >= traj.time[0]) & (t <= traj.time[-1])
    t = t[inside]
    if len(t) == 0:
        return {"n_withheld": int(withheld.sum()), "n_scored": 0}
    lat = np.interp(t, traj.time, traj.lat)
    lon = np.interp(t, traj.time, np.unwrap(traj.lon))
    de, dn, _ = lla_difference_enu(lat, lon, 0.0, gnss.lat[good][inside], gnss.lon[good][inside], 0.0)
    herr = np.hypot(de, dn)
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
    }


def process_logs(imu_path, gnss_path, config_path=None, out_path="out/trajectory.csv", smooth=False,
                 outages: list[str] | None = None, console=None) -> dict:
    """Run the whole ``aidnav process`` job; returns the summary dict (also written as JSON + text)."""
    from aidnav.filters.loose import run_loose, to_trajectory
    from aidnav.io.interchange import write_trajectory

    t_start = _time.perf_counter()
    notes: list[str] = []
    if config_path is None:
        cfg = LooseConfig()
        notes.append("no --config: defaults for a consumer MEMS IMU (ARW 0.3 deg/sqrt(h), "
                     "VRW 0.1 m/s/sqrt(h), "
                     "gyro bias 100 deg/h, accel bias 5 mg), no lever arm, automatic alignment "
                     "(static roll/pitch, heading from GNSS course), ZUPT on, NHC off")
    else:
        cfg = load_config(config_path)
    imu = read_imu_any(imu_path)
    gnss = read_gnss_any(gnss_path, height_offset_m=cfg.gnss.height_offset_m)
    if len(imu) < 2:
        raise DataError(imu_path, None, "fewer than 2 IMU samples")
    if len(gnss) < 1:
        raise DataError(gnss_path, None, "no GNSS fixes")
    t_read = _time.perf_counter()
    wins = outage_windows([parse_outage(o) for o in (outages or [])], gnss.time[0], gnss.time[-1])
    withheld = np.zeros(len(gnss), bool)
    for a, b in wins:
        withheld |= (gnss.time >= a) & (gnss.time < b)
    events: list[str] = []
    res = run_loose(imu, gnss, cfg, withheld=withheld, smooth=smooth, events=events)
    t_filt = _time.perf_counter()
    traj = to_trajectory(res)
    out_path = Path(out_path)
    out_path.parent.mkdir(parents=True, exist_ok=True)
    write_trajectory(traj, out_path)
    t_write = _time.perf_counter()
    rec = res.records
    summary = {
        "imu": str(imu_path), "gnss": str(gnss_path), "config": str(config_path) if config_path else None,
        "output": str(out_path), "smoothed": res.smoothed,
        "time_scale": "input (GPS seconds of week for GNSS-timed logs)",
        "imu_samples": len(imu), "imu_rate_hz": imu.rate_hz, "gnss_fixes": len(gnss),
        "gnss_withheld": int(withheld.sum()),
        "gnss_position_accepted": int((rec["pos_status"] == 1).sum()),
        "gnss_position_rejected": int((rec["pos_status"] == 0).sum()),
        "gnss_velocity_accepted": int((rec["vel_status"] == 1).sum()),
        "gnss_velocity_rejected": int((rec["vel_status"] == 0).sum()),
        "rejected_fix_times": [float(t) for t in gnss.time[rec["pos_status"] == 0]][:100],
        "counts": res.counts,
        "outage_windows": [[a, b] for a, b in wins],
        "events": imu.events + gnss.events + events,
        "notes": notes,
        "timing_s": {"read": t_read - t_start, "filter": t_filt - t_read, "write": t_write - t_filt},
    }
    if wins:
        summary["outage_score"] = score_outages(traj, gnss, wins, withheld)
        if res.smoothed and res.forward_state is not None:
            from aidnav.filters.loose import LooseResult

            fwd = to_trajectory(LooseResult(res.time, res.forward_state, res.bias, res.forward_pdiag,
                                            res.node_time))
            summary["outage_score_forward"] = score_outages(fwd, gnss, wins, withheld)
    base = out_path.with_suffix("")
    Path(str(base) + "_summary.json").write_text(json.dumps(summary, indent=2, default=float))
    Path(str(base) + "_summary.txt").write_text(format_summary(summary))
    return summary


def format_summary(s: dict) -> str:
    """Human-readable summary text."""
    lines = [f"aidnav process: {s['imu']} + {s['gnss']}",
             f"output: {s['output']} (smoothed: {s['smoothed']})",
             f"IMU samples {s['imu_samples']} at {s['imu_rate_hz']:.1f} Hz; GNSS fixes {s['gnss_fixes']}, "
             f"withheld {s['gnss_withheld']}",
             f"GNSS position accepted {s['gnss_position_accepted']}, rejected {s['gnss_position_rejected']}; "
             f"velocity accepted {s['gnss_velocity_accepted']}, rejected {s['gnss_velocity_rejected']}",
             f"counts: {s['counts']}"]
    for key, title in (("outage_score", "outage score"), ("outage_score_forward", "outage score (forward)")):
        if key in s:
            o = s[key]
            if o.get("end_error_median_m") is not None:
                lines.append(f"{title}: {o['n_outages']} outages, end-of-outage horizontal error median "
                             f"{o['end_error_median_m']:.2f} m, p95 {o['end_error_p95_m']:.2f} m, max "
                             f"{o['end_error_max_m']:.2f} m; RMS over {o['n_scored']} withheld fixes "
                             f"{o['rms_m']:.3f} m")
    lines += [f"event: {e}" for e in s["events"]] + [f"note: {n}" for n in s["notes"]]
    return "\n".join(lines) + "\n"
