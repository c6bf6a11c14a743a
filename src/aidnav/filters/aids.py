"""Aids are data: a measurement source is an :class:`Aid` (its data and its :class:`AidKind`) in a list.

An :class:`AidKind` holds everything the loose filter and ``aidnav process`` need to use one kind of aid
besides GNSS: its measurement model id (:mod:`aidnav.filters.measurements`), the section of
:class:`aidnav.filters.config.LooseConfig` with its settings, its reader (in :mod:`aidnav.io`), how its
data become engine records, its calibration state and model parameters, whether it sees the vehicle frame
(then it needs the IMU → vehicle mounting), an optional initial heading, and its CLI help. The drivers
(:func:`aidnav.filters.loose.run_loose`, :func:`aidnav.filters.stream.stream_loose`) and the process job
take ``aids=[Aid, ...]``; the CLI's ``--aid NAME=FILE``, the summary's per-aid entries and the update
counts come from :data:`AIDS`. Adding an aid: ``docs/adding-an-aid.md``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from aidnav.errors import InputError
from aidnav.units import DEG

from . import measurements as ms

ROW_W = 6  # width of an aid's engine record row (the GNSS position record's: lat, lon, h, σ E, N, U)


@dataclass(frozen=True)
class AidKind:
    """One kind of aid (module doc). ``rows(data, section) → (t, rows (k, ≤ ROW_W), use)``;
    ``read(path, section) → data`` (imports its :mod:`aidnav.io` reader when called); ``params(cfg,
    cbv) → (P,)`` the model's parameters (``cbv``: C_b^v of the configured mounting, row-major);
    ``state``: the calibration state (:data:`aidnav.filters.layout.AUX_NAMES`) added when
    ``state_on(section)``; ``heading(data, t, section) → (ψ, σ) [rad] or None``: an initial heading."""

    name: str
    model: int
    section: str
    rows: Callable
    read: Callable
    help: str
    state: str | None = None
    state_on: Callable | None = None
    params: Callable | None = None
    vehicle_frame: bool = False
    heading: Callable | None = None


@dataclass
class Aid:
    """A measurement source: ``data`` (the container its reader or simulator gives, with ``time`` on the
    GNSS time scale) of kind ``kind``; ``source`` names where it came from (the summary)."""

    kind: AidKind
    data: object
    source: str | None = None

    @property
    def name(self) -> str:
        return self.kind.name


def _value_rows(value: str, std_key: str):
    """rows() of a scalar aid: (value, σ) per sample, σ from the data or the section's ``std_key``."""

    def rows(data, sec):
        v = np.asarray(getattr(data, value), float)
        k = len(v)
        std = np.full(k, getattr(sec, std_key)) if getattr(data, "std", None) is None else \
            np.asarray(data.std, float)
        return np.asarray(data.time, float), np.column_stack([v, std]), np.isfinite(v) & np.isfinite(std)

    return rows


def _read_odometer(path, sec):
    from aidnav.io.aux_sensors import read_odometer_csv  # lazy: readers load with their aid

    return read_odometer_csv(path)


def _read_baro(path, sec):
    from aidnav.io.aux_sensors import read_baro_csv  # lazy: readers load with their aid

    return read_baro_csv(path)


def _read_mag(path, sec):
    from aidnav.io.aux_sensors import read_heading_csv  # lazy: readers load with their aid

    return read_heading_csv(path, declination_deg=sec.declination_deg)


def _vehicle_params(lever_of):
    def params(cfg, cbv):
        V = ms.vehicle
        p = np.zeros(V.V_CBV + 9)
        p[V.V_LEVER:V.V_LEVER + 3], p[V.V_CBV:V.V_CBV + 9] = lever_of(cfg), cbv
        return p

    return params


def _mag_rows(data, sec):
    t, rows, use = _value_rows("heading", "sigma_deg")(data, sec)
    if getattr(data, "std", None) is None:
        rows[:, 1] *= DEG  # the section's σ is in degrees; the data's in radians
    return t, rows, use


def _mag_heading(data, t, sec):
    """Circular mean of the headings within 1 s of ``t`` and their σ (None: none there)."""
    tt, rows, use = _mag_rows(data, sec)
    near = use & (np.abs(tt - t) <= 1.0)
    if not near.any():
        return None
    psi = float(np.arctan2(np.sin(rows[near, 0]).mean(), np.cos(rows[near, 0]).mean()))
    return psi % (2 * np.pi), float(np.median(rows[near, 1]))


ODOMETER = AidKind(
    "odometer", ms.M_ODO, "odometer", _value_rows("speed", "sigma_m_s"), _read_odometer,
    "odometer CSV (time_s, speed_m_s or speed_km_h [, speed_std_m_s]) on the GNSS time scale",
    state="odometer_scale", state_on=lambda sec: sec.scale_factor,
    params=_vehicle_params(lambda cfg: cfg.odometer.lever_arm_m), vehicle_frame=True)
BARO = AidKind(
    "baro", ms.M_BARO, "baro", _value_rows("height", "sigma_m"), _read_baro,
    "barometer CSV (time_s, height_m or height_ft [, height_std_m]) on the GNSS time scale",
    state="baro_bias", state_on=lambda sec: sec.bias)
MAG = AidKind(
    "mag", ms.M_MAG, "mag", _mag_rows, _read_mag,
    "magnetometer heading CSV (time_s, heading_deg magnetic [, heading_std_deg]) on the GNSS time scale; "
    "mag.declination_deg makes it true", heading=_mag_heading)

#: every kind of aid, by name (the order of their calibration states in the layout)
AIDS = {k.name: k for k in (ODOMETER, BARO, MAG)}


def aid(name: str, data, source: str | None = None) -> Aid:
    """The :class:`Aid` of kind ``name`` (a key of :data:`AIDS`) holding ``data``."""
    if name not in AIDS:
        raise InputError(f"unknown aid {name!r}: expected one of {', '.join(AIDS)}")
    return Aid(AIDS[name], data, source)


def parse_aid(text: str) -> tuple[str, Path]:
    """``NAME=FILE`` (the CLI's ``--aid``) → (name, path)."""
    name, sep, path = text.partition("=")
    if not sep or not path or name not in AIDS:
        raise InputError(f"--aid {text}: expected NAME=FILE with NAME one of {', '.join(AIDS)}")
    return name, Path(path)


def read_aid(name: str, path, cfg) -> Aid:
    """Read the file of aid ``name`` with its reader and the settings of its section of ``cfg``."""
    kind = AIDS[name]
    return Aid(kind, kind.read(path, getattr(cfg, kind.section)), str(path))


def kinds(aids) -> list[AidKind]:
    """The kinds among ``aids``, in the order of :data:`AIDS`."""
    have = {a.kind.name for a in aids}
    return [k for k in AIDS.values() if k.name in have]


def layout_states(cfg, aids) -> list[str]:
    """The calibration states the given aids add to the layout (in the order of :data:`AIDS`)."""
    return [k.state for k in kinds(aids) if k.state and k.state_on(getattr(cfg, k.section))]


def vehicle_frame(aids) -> bool:
    """Whether an aid sees the vehicle frame (the IMU → vehicle mounting is then observable and needed)."""
    return any(a.kind.vehicle_frame for a in aids)


def records(cfg, aids):
    """Engine record fields of ``aids``: lists of (t, model, rows (k, ROW_W), use)."""
    out = []
    for a in aids:
        t, rows, use = a.kind.rows(a.data, getattr(cfg, a.kind.section))
        k = len(t)
        full = np.zeros((k, ROW_W))
        full[:, :rows.shape[1]] = rows
        out.append((t, np.full(k, a.kind.model), full, use))
    return out


def initial_heading(cfg, aids, t0):
    """(ψ, σ, name) of the first aid that gives a heading at ``t0``, or None."""
    for a in aids:
        if a.kind.heading is not None:
            h = a.kind.heading(a.data, t0, getattr(cfg, a.kind.section))
            if h is not None:
                return (*h, a.kind.name)
    return None
