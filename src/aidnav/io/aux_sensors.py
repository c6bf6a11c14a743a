"""Odometer and barometer inputs: containers and CSV column readers (units converted here, SI after).

CSV files with a header; columns (case-insensitive, units in the name):

* odometer: ``time_s`` and one of ``speed_m_s`` / ``speed_km_h``; optional ``speed_std_m_s``;
* barometer: ``time_s`` and one of ``height_m`` (barometric height, any datum: the filter's bias state
  absorbs the offset) / ``height_ft``; optional ``height_std_m``;
* magnetometer heading: ``time_s`` and ``heading_deg`` (magnetic, of the IMU's forward axis, clockwise
  from magnetic North); optional ``heading_std_deg``; the declination is added here (true heading after).

A row whose value is empty or not a number is reported as an error naming file and line; times must
increase strictly.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from aidnav.io.errors import DataError

FT = 0.3048


@dataclass
class OdometerData:
    """Odometer speed: time [s], forward speed of the wheel point [m/s] (signed), optional 1σ [m/s]."""

    time: np.ndarray
    speed: np.ndarray
    std: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.time)


@dataclass
class BaroData:
    """Barometric height: time [s], height [m] (datum and bias unknown to the filter), optional 1σ [m]."""

    time: np.ndarray
    height: np.ndarray
    std: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.time)


@dataclass
class HeadingData:
    """Heading of the IMU's forward axis: time [s], true heading [rad] in [0, 2π), optional 1σ [rad]."""

    time: np.ndarray
    heading: np.ndarray
    std: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.time)


def _read_columns(path, choices: dict[str, float], std_name: str):
    path = Path(path)
    with path.open(newline="") as f:
        rows = list(csv.reader(f))
    if not rows:
        raise DataError(path, None, "empty file")
    head = [h.strip().lower() for h in rows[0]]
    if "time_s" not in head:
        raise DataError(path, 1, f"no time_s column (columns: {head})")
    val = next((c for c in choices if c in head), None)
    if val is None:
        raise DataError(path, 1, f"none of the columns {list(choices)} (columns: {head})")
    cols = [head.index("time_s"), head.index(val)] + ([head.index(std_name)] if std_name in head else [])
    data = np.full((len(rows) - 1, len(cols)), np.nan)
    for i, r in enumerate(rows[1:]):
        try:
            data[i] = [float(r[c]) for c in cols]
        except (ValueError, IndexError):
            raise DataError(path, i + 2, f"not a number in columns {[head[c] for c in cols]}: {r}") from None
    if not np.all(np.isfinite(data)):
        i = int(np.flatnonzero(~np.all(np.isfinite(data), axis=1))[0])
        raise DataError(path, i + 2, "NaN or infinite value")
    if len(data) > 1 and np.any(np.diff(data[:, 0]) <= 0):
        i = int(np.flatnonzero(np.diff(data[:, 0]) <= 0)[0])
        raise DataError(path, i + 3, "time does not increase")
    std = data[:, 2] if len(cols) == 3 else None
    return data[:, 0], data[:, 1] * choices[val], std


def read_odometer_csv(path) -> OdometerData:
    """Odometer CSV (module doc) → :class:`OdometerData` in m/s."""
    t, v, s = _read_columns(path, {"speed_m_s": 1.0, "speed_km_h": 1.0 / 3.6}, "speed_std_m_s")
    return OdometerData(t, v, s)


def read_baro_csv(path) -> BaroData:
    """Barometer CSV (module doc) → :class:`BaroData` in metres."""
    t, h, s = _read_columns(path, {"height_m": 1.0, "height_ft": FT}, "height_std_m")
    return BaroData(t, h, s)


def read_heading_csv(path, declination_deg: float = 0.0) -> HeadingData:
    """Magnetometer heading CSV (module doc) → :class:`HeadingData`: true heading [rad] = magnetic heading +
    ``declination_deg`` (east positive), wrapped to [0, 2π); σ in radians."""
    t, h, s = _read_columns(path, {"heading_deg": np.pi / 180.0}, "heading_std_deg")
    return HeadingData(t, (h + np.radians(declination_deg)) % (2 * np.pi),
                       None if s is None else np.radians(s))
