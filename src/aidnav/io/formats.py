"""One place that recognises every IMU, GNSS and trajectory file aidnav reads, and reads it.

Formats (name → reader):

IMU (:data:`IMU_FORMATS`)
  ``interchange``     aidnav CSV (``,`` ``;`` or tab) / Parquet, header with ``time`` (:mod:`.interchange`)
  ``rtklibexplorer``  raw rtklibexplorer IMU CSV (7 fields, no header) + ``<file>.tag`` (:mod:`.logs`)
  ``kfgins``          KF-GINS IMU text ``t dθ dv`` FRD (:mod:`.kfgins`)
  ``rosbag``          sensor_msgs/Imu in a ROS 1 / ROS 2 bag (:mod:`.rosbag`)
GNSS (:data:`GNSS_FORMATS`)
  ``interchange``     aidnav CSV / Parquet with ``time, lat_deg, lon_deg, height_m``
  ``rtklib-pos``      RTKLIB ``.pos`` solution (:mod:`.rtklib`)
  ``kfgins``          KF-GINS GNSS text ``t lat lon h σN σE σD``
  ``nmea``            NMEA 0183 GGA + RMC/VTG (+ GST) (:mod:`.nmea`)
  ``ubx``             u-blox UBX NAV-PVT (:mod:`.ubx`)
  ``rosbag``          sensor_msgs/NavSatFix (+ TwistStamped) in a ROS bag
Trajectories (:func:`read_trajectory_any`): ``interchange``, ``kfgins-nav`` (KF-GINS ``.nav``), and any
GNSS format above (a position/velocity reference without attitude).

Detection looks at the content (magic bytes, header line, field count and values), the extension
only where the content is ambiguous; ``fmt=`` overrides it. A file that matches none raises
:class:`DataError` "unknown format: expected one of …" naming what was seen.

The **datum (height) offset** of GNSS data is applied here, once, for every format
(:func:`read_gnss` ``height_offset_m``: h_ellipsoidal = h_file + offset); no other code adds it. Each
reader says what its heights are (``GnssData.height_datum``, :data:`HEIGHT_DATUM`): the offset is added
only where the file does not declare ellipsoidal heights; given for a file that does (a ROS NavSatFix,
UBX NAV-PVT ``height``, NMEA GGA with its geoid separation, an RTKLIB ``.pos`` whose header says
``ellipsoidal``) it is not applied and a warning names both.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from aidnav.data import GnssData, ImuData, Trajectory
from aidnav.io import kfgins, rosbag
from aidnav.io._std import ZERO_POS_STD_FLOOR_M, ZERO_VEL_STD_FLOOR_M_S
from aidnav.io.errors import DataError
from aidnav.io.nmea import read_nmea
from aidnav.io.rosbag import is_rosbag
from aidnav.io.rtklib import read_pos
from aidnav.io.ubx import read_ubx

__all__ = ["IMU_FORMATS", "GNSS_FORMATS", "TRAJECTORY_FORMATS", "HEIGHT_DATUM", "apply_height_offset",
           "detect_imu_format", "detect_gnss_format", "detect_trajectory_format", "read_imu", "read_gnss",
           "read_trajectory_any", "gnss_to_trajectory"]

IMU_FORMATS = {
    "interchange": "aidnav interchange CSV/Parquet (header with time and gyro_*_rad_s/accel_*_m_s2 or "
                   "dtheta_*_rad/dv_*_m_s)",
    "rtklibexplorer": "raw rtklibexplorer IMU CSV (ax,ay,az [g], gx,gy,gz [deg/s], stamp [ms]; no header) "
                      "with its RTKLIB time tag FILE.tag",
    "kfgins": "KF-GINS IMU text (7 columns: t [s], dθ x y z [rad], dv x y z [m/s], FRD)",
    "rosbag": "ROS 1 .bag / ROS 2 bag directory with sensor_msgs/Imu",
}
GNSS_FORMATS = {
    "interchange": "aidnav interchange CSV/Parquet (header with time, lat_deg, lon_deg, height_m)",
    "rtklib-pos": "RTKLIB .pos solution (lat/lon/height, GPST)",
    "kfgins": "KF-GINS GNSS text (7 columns: t [s], lat lon [deg], h [m], σ N E D [m])",
    "nmea": "NMEA 0183 log (GGA + RMC/VTG, optional GST)",
    "ubx": "u-blox UBX log with NAV-PVT",
    "rosbag": "ROS 1 .bag / ROS 2 bag directory with sensor_msgs/NavSatFix",
}
#: What the heights of each GNSS format are (the reader sets ``GnssData.height_datum`` per file)
HEIGHT_DATUM = {
    "interchange": "unknown (the file does not say; aidnav writes ellipsoidal heights)",
    "rtklib-pos": "ellipsoidal or geodetic (MSL) as the header line '(lat/lon/height=WGS84/…)' says; "
                  "unknown without it",
    "kfgins": "unknown (the file does not say)",
    "nmea": "ellipsoidal: GGA altitude (MSL) + the GGA geoid separation; MSL when the field is empty",
    "ubx": "ellipsoidal (NAV-PVT height; hMSL not used)",
    "rosbag": "ellipsoidal (sensor_msgs/NavSatFix altitude, by the message definition)",
}
TRAJECTORY_FORMATS = {
    "interchange": "aidnav interchange trajectory CSV/Parquet",
    "kfgins-nav": "KF-GINS navigation result .nav (11 columns: week sow lat lon h vN vE vD roll pitch yaw)",
    **{f"gnss:{k}": v for k, v in GNSS_FORMATS.items()},
}

_HEAD_BYTES = 65536
_NUM = re.compile(r"^[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$")
_SPLIT = re.compile(r"[,;\s]+")
_NMEA = re.compile(rb"^\$[A-Z]{2}[A-Z]{3},")
_RTKLIB_TIME = re.compile(r"^\d{4}[/-]\d{2}[/-]\d{2}$")


def _unknown(path, kinds: dict, seen: str):
    exp = "; ".join(f"{k} — {v}" for k, v in kinds.items())
    raise DataError(path, None, f"unknown format: expected one of: {exp}. Seen: {seen}")


class _Sniff:
    """What the first bytes of a file say about it."""

    def __init__(self, path: Path):
        self.path = path
        if not path.exists():
            raise DataError(path, None, "file not found")
        self.is_dir = path.is_dir()
        self.head = b""
        if not self.is_dir:
            try:
                with open(path, "rb") as f:
                    self.head = f.read(_HEAD_BYTES)
            except OSError as e:
                raise DataError(path, None, f"cannot read file: {e.strerror or e}") from None
        self.suffix = path.suffix.lower()
        text = self.head.decode("utf-8", errors="replace").lstrip("\ufeff").replace('"', "")
        lines = text.split("\n")
        if len(self.head) == _HEAD_BYTES and len(lines) > 1:
            lines = lines[:-1]  # the last one may be cut
        self.lines = [ln.strip() for ln in lines]
        self.data = [ln for ln in self.lines if ln and not ln.startswith(("#", "%"))]
        self.first = self.data[0] if self.data else ""
        h = self.head[:4096]
        self.binary = b"\x00" in h or (bool(h) and sum(b < 9 or 13 < b < 32 for b in h) > 0.05 * len(h))

    def rosbag(self) -> bool:
        return is_rosbag(self.path)

    def parquet(self) -> bool:
        return self.head[:4] == b"PAR1" or self.suffix in (".parquet", ".pq")

    def header_names(self) -> list[str] | None:
        """Column names when the first data line is a header (has a letter-led field), else None."""
        if not self.first or self.binary:
            return None
        fields = [f for f in _SPLIT.split(self.first) if f]
        if any(not _NUM.match(f) and f.lower() not in ("nan", "-nan", "inf", "-inf") for f in fields):
            if re.search(r"[,;\t]", self.first):
                return [f.strip() for f in re.split(r"[,;\t]", self.first)]
            return fields
        return None

    def numeric_rows(self, n: int = 50) -> np.ndarray | None:
        """The first data lines as a float array if they are all numeric with one field count."""
        rows = []
        for ln in self.data[:n]:
            f = [x for x in _SPLIT.split(ln) if x]
            if not all(_NUM.match(x) or x.lower() in ("nan", "-nan", "inf", "-inf") for x in f):
                return None
            rows.append([float(x) for x in f])
        if not rows:
            return None
        # the modal field count (a raw logger may start or end in the middle of a line)
        counts = [len(r) for r in rows]
        k = max(set(counts), key=counts.count)
        if counts.count(k) < 0.8 * len(rows):
            return None
        return np.asarray([r for r in rows if len(r) == k])

    def delimiter_note(self) -> str:
        if not self.first:
            return "an empty file" if not self.head else "no data lines"
        if self.binary:
            return f"binary data (first bytes {self.head[:8]!r})"
        return f"first data line {self.first[:80]!r}"


def _ubx_nav_pvt(head: bytes) -> bool:
    """True when ``head`` holds a whole UBX NAV-PVT frame with a valid checksum (not just its sync bytes,
    which binary junk in an NMEA stream may contain)."""
    i = head.find(b"\xb5\x62\x01\x07")
    while 0 <= i <= len(head) - 8:
        n = int.from_bytes(head[i + 4:i + 6], "little")
        frame = head[i + 2:i + 6 + n]
        if len(frame) == 4 + n and i + 8 + n <= len(head):
            a = b = 0
            for c in frame:
                a = (a + c) & 0xFF
                b = (b + a) & 0xFF
            if head[i + 6 + n:i + 8 + n] == bytes((a, b)):
                return True
        i = head.find(b"\xb5\x62\x01\x07", i + 1)
    return False


def _increasing(x: np.ndarray) -> bool:
    return len(x) < 2 or bool(np.all(np.diff(x) > 0))


def _sniff_container(path, kinds: dict) -> tuple[Path, _Sniff, str | None]:
    """The first checks of every detector: a ROS bag, a directory, an empty file, a Parquet file.

    Returns the path, its sniffed head and the format when these checks settle it (else None)."""
    path = Path(path)
    s = _Sniff(path)
    if s.rosbag():
        return path, s, "rosbag"
    if s.is_dir:
        _unknown(path, kinds, "a directory without metadata.yaml")
    if not s.head:
        raise DataError(path, None, "empty file")
    return path, s, "interchange" if s.parquet() else None


def detect_imu_format(path, need_time_tag: bool = True) -> str:
    """The IMU format of ``path`` (a key of :data:`IMU_FORMATS`), from its content.

    Raises DataError "unknown format: expected one of …" (naming what was seen) when none matches, and
    a specific message for a raw rtklibexplorer log whose ``.tag`` file is missing (with
    ``need_time_tag`` False such a log is "rtklibexplorer": for jobs that use only the sample intervals,
    e.g. the noise characterisation)."""
    path, s, fmt = _sniff_container(path, IMU_FORMATS)
    if fmt:
        return fmt
    names = s.header_names()
    if names is not None:
        if "time" in names:
            return "interchange"
        _unknown(path, IMU_FORMATS, f"a header line without a 'time' column: {', '.join(names)[:200]}")
    rows = s.numeric_rows()
    if rows is not None:
        k = rows.shape[1]
        tag = path.with_name(path.name + ".tag")
        if k == 7 and "," in s.first and tag.exists():
            return "rtklibexplorer"
        if k in (7, 8) and _increasing(rows[:, 0]) and np.all(np.abs(rows[:, 1:4]) < 1.0):
            return "kfgins"
        if k in (7, 13) and _increasing(rows[:, 0]) and np.all(np.abs(rows[:, 1]) <= 90) and \
                np.all(rows[:, 4:7] >= 0) and np.any(np.abs(rows[:, 1:3]) > 1):
            raise DataError(path, None, "looks like a KF-GINS GNSS file (t lat lon h σN σE σD), not IMU "
                                        "increments: check the file given for the IMU")
        if k == 7 and "," in s.first and _increasing(rows[:, 6]):
            if not need_time_tag:
                return "rtklibexplorer"
            raise DataError(path, None, "looks like a raw rtklibexplorer IMU log (7 comma-separated fields, "
                                        f"ms stamp last) but its time tag {tag.name} is missing: it is "
                                        "needed to map the IMU stamps to GPS time")
        _unknown(path, IMU_FORMATS, f"a headerless table of {k} numeric columns ({s.delimiter_note()})")
    _unknown(path, IMU_FORMATS, s.delimiter_note())


def detect_gnss_format(path) -> str:
    """The GNSS format of ``path`` (a key of :data:`GNSS_FORMATS`), from its content."""
    path, s, fmt = _sniff_container(path, GNSS_FORMATS)
    if fmt:
        return fmt
    if _ubx_nav_pvt(s.head) or (s.suffix == ".ubx" and b"\xb5\x62" in s.head):
        return "ubx"
    nmea_lines = sum(bool(_NMEA.match(ln.encode(errors="replace"))) for ln in s.lines[:200])
    if nmea_lines and nmea_lines >= 0.5 * min(len([x for x in s.lines[:200] if x]), 200):
        return "nmea"
    if b"\xb5\x62" in s.head and s.binary:
        return "ubx"
    if any(ln.startswith("%") for ln in s.lines[:50]) or s.suffix == ".pos" or (
            s.first and _RTKLIB_TIME.match(s.first.split()[0])):
        return "rtklib-pos"
    names = s.header_names()
    if names is not None:
        if "time" in names and "lat_deg" in names:
            return "interchange"
        _unknown(path, GNSS_FORMATS, f"a header line without time/lat_deg columns: {', '.join(names)[:200]}")
    rows = s.numeric_rows()
    if rows is not None:
        k = rows.shape[1]
        if k in (7, 13) and _increasing(rows[:, 0]) and np.all(np.abs(rows[:, 1:4]) < 1e-2):
            raise DataError(path, None, "looks like a KF-GINS IMU file (t and small increments), not GNSS "
                                        "fixes (t lat lon h σN σE σD): check the file given for GNSS")
        if k in (7, 13) and _increasing(rows[:, 0]) and np.all(np.abs(rows[:, 1]) <= 90):
            return "kfgins"
        _unknown(path, GNSS_FORMATS, f"a headerless table of {k} numeric columns ({s.delimiter_note()})")
    _unknown(path, GNSS_FORMATS, s.delimiter_note())


def detect_trajectory_format(path) -> str:
    """``interchange`` (a trajectory with attitude columns), ``kfgins-nav`` or ``gnss:<format>``."""
    path = Path(path)
    s = _Sniff(path)
    if not s.is_dir and s.head and not s.binary:
        names = s.header_names()
        if names is not None and "heading_deg" in names:
            return "interchange"
        rows = s.numeric_rows()
        if rows is not None and rows.shape[1] == 11 and _increasing(rows[:, 1]):
            return "kfgins-nav"
    if s.parquet():
        import pyarrow.parquet as pq  # lazy: pyarrow is heavy to import

        try:
            names = pq.ParquetFile(path).schema_arrow.names
        except Exception:  # noqa: BLE001  (a broken Parquet file: the reader names the problem)
            names = []
        if "heading_deg" in names:
            return "interchange"
    try:
        return "gnss:" + detect_gnss_format(path)
    except DataError as e:
        if "unknown format" in e.problem:
            _unknown(path, TRAJECTORY_FORMATS, s.delimiter_note())
        raise


def _check_fmt(fmt: str, kinds: dict, what: str):
    if fmt not in kinds:
        raise ValueError(f"unknown {what} format {fmt!r}: expected one of {', '.join(kinds)}")


def read_imu(path, fmt: str | None = None, *, topic: str | None = None, axes: str | None = None,
             stamps: str = "utc", tag_path=None) -> ImuData:
    """Read an IMU log of any known format → :class:`ImuData` (increments [rad], [m/s], body RFU;
    GPS seconds of week for GNSS-timed logs). The format is detected unless ``fmt`` names it.

    topic, stamps : ROS bags (:func:`aidnav.io.rosbag.read_imu`). axes : sensor axes of a ROS bag
    ("FLU" default) or a raw rtklibexplorer log ("RFU" default). tag_path : rtklibexplorer time tag.
    The format is recorded in the first event."""
    path = Path(path)
    how = "given"
    if fmt is None:
        fmt, how = detect_imu_format(path), "detected"
    _check_fmt(fmt, IMU_FORMATS, "IMU")
    if topic is not None and fmt != "rosbag":
        raise DataError(path, None, f"an IMU topic ({topic}) was given but this is a {fmt} file, not a "
                                    "ROS bag")
    if fmt == "interchange":
        from aidnav.io import interchange  # lazy: pulls in pyarrow

        imu = interchange.read_imu(path)
    elif fmt == "rtklibexplorer":
        from aidnav.io.logs import read_rtklibexplorer_imu  # lazy: pulls in pyarrow

        imu = read_rtklibexplorer_imu(path, tag_path=tag_path, axes=axes or "RFU")
    elif fmt == "kfgins":
        imu = kfgins.read_imu(path)
    else:
        imu = rosbag.read_imu(path, topic=topic, axes=axes or "FLU", stamps=stamps)
    imu.events.insert(0, f"{path.name}: IMU format {fmt} ({how})")
    return imu


def read_gnss(path, fmt: str | None = None, height_offset_m: float = 0.0, *,
              min_pos_std_m: float = ZERO_POS_STD_FLOOR_M, min_vel_std_m_s: float = ZERO_VEL_STD_FLOOR_M_S,
              topic: str | None = None, vel_topic: str | None = None, stamps: str = "utc",
              date=None) -> GnssData:
    """Read GNSS fixes of any known format → :class:`GnssData` (lat/lon [rad], **ellipsoidal** height
    [m], ENU velocity [m/s] with NaN = not measured, σ ENU or None, GPS seconds of week).

    height_offset_m : datum offset added to every height, here and nowhere else (e.g. −21.4 m for the
        rtklibexplorer ``.pos`` files, which hold heights above MSL); stated in the events.
    min_pos_std_m, min_vel_std_m_s : the value a σ of exactly 0 is floored to (warning event).
    topic, vel_topic, stamps : ROS bags. date : UTC date of an NMEA log without RMC ('YYYY-MM-DD').
    """
    path = Path(path)
    how = "given"
    if fmt is None:
        fmt, how = detect_gnss_format(path), "detected"
    _check_fmt(fmt, GNSS_FORMATS, "GNSS")
    if (topic is not None or vel_topic is not None) and fmt != "rosbag":
        raise DataError(path, None, f"a GNSS topic ({topic or vel_topic}) was given but this is a {fmt} "
                                    "file, not a ROS bag")
    if fmt == "interchange":
        from aidnav.io import interchange  # lazy: pulls in pyarrow

        g = interchange.read_gnss(path, min_pos_std_m=min_pos_std_m, min_vel_std_m_s=min_vel_std_m_s)
    elif fmt == "rtklib-pos":
        g = read_pos(path, min_pos_std_m=min_pos_std_m, min_vel_std_m_s=min_vel_std_m_s)
    elif fmt == "kfgins":
        g = kfgins.read_gnss(path, min_pos_std_m=min_pos_std_m)
    elif fmt == "nmea":
        g = read_nmea(path, date=date, min_pos_std_m=min_pos_std_m)
    elif fmt == "ubx":
        g = read_ubx(path, min_pos_std_m=min_pos_std_m, min_vel_std_m_s=min_vel_std_m_s)
    else:
        g = rosbag.read_gnss(path, topic=topic, vel_topic=vel_topic, stamps=stamps,
                             min_pos_std_m=min_pos_std_m)
    g.events.insert(0, f"{path.name}: GNSS format {fmt} ({how})")
    apply_height_offset(g, height_offset_m, path.name, fmt)
    return g


def apply_height_offset(g: GnssData, height_offset_m: float, name: str, fmt: str) -> None:
    """Add the configured datum offset to ``g.height`` unless the file declares ellipsoidal heights
    (then a warning names the file's datum and the offset not applied). Records the offset applied in
    ``g.height_offset_m`` and says what was done in ``g.events``."""
    off = float(height_offset_m or 0.0)
    if g.height_datum == "ellipsoid":
        if off:
            g.events.append(f"warning: {name}: the file gives ellipsoidal heights ({fmt}: "
                            f"{HEIGHT_DATUM.get(fmt, 'declared by the file')}); the height offset "
                            f"{off:+.3f} m "
                            "(gnss.height_offset_m / --height-offset) is NOT applied: remove it from the "
                            "configuration for this file")
        else:
            g.events.append(f"{name}: heights are ellipsoidal as the file declares ({fmt}); no offset")
        return
    if off:
        g.height = g.height + off
        g.height_offset_m = float(g.height_offset_m) + off
        kind = "above mean sea level" if g.height_datum == "msl" else "of a datum the file does not state"
        g.events.append(f"{name}: heights {kind}: datum offset {off:+.3f} m added to every height "
                        "(h_ellipsoidal = h_file + gnss.height_offset_m), once, by the reader")
    elif g.height_datum == "msl":
        g.events.append(f"warning: {name}: heights are above mean sea level with the geoid separation "
                        "unknown, and no height offset is configured: they are taken as ellipsoidal "
                        "(set gnss.height_offset_m / --height-offset to the geoid undulation)")


def gnss_to_trajectory(g: GnssData) -> Trajectory:
    """GNSS fixes as a :class:`Trajectory` (a reference without attitude): same time, lat/lon, height,
    velocity (NaN where not measured or absent), attitude all NaN, σ carried over, quality in extra."""
    m = len(g.time)
    vel = np.full((m, 3), np.nan) if g.vel is None else np.asarray(g.vel, dtype=float)
    extra = {} if g.quality is None else {"quality": np.asarray(g.quality)}
    return Trajectory(time=g.time, lat=g.lat, lon=g.lon, height=g.height, vel=vel,
                      rph=np.full((m, 3), np.nan), std_pos=g.std_pos, std_vel=g.std_vel, extra=extra,
                      week=g.week)


def read_trajectory_any(path, fmt: str | None = None, height_offset_m: float = 0.0,
                        notes: list[str] | None = None, **gnss_options) -> Trajectory:
    """Read a trajectory of any known format: an interchange trajectory, a KF-GINS ``.nav`` result, or
    GNSS fixes of any GNSS format (:func:`read_gnss`, with ``height_offset_m`` applied, converted by
    :func:`gnss_to_trajectory`). ``notes`` receives the reader's events. fmt : a key of
    :data:`TRAJECTORY_FORMATS` (``"gnss:<format>"`` for GNSS files)."""
    path = Path(path)
    if fmt is None:
        fmt = detect_trajectory_format(path)
    _check_fmt(fmt, TRAJECTORY_FORMATS, "trajectory")
    if fmt == "interchange":
        from aidnav.io import interchange  # lazy: pulls in pyarrow

        traj = interchange.read_trajectory(path)
        if height_offset_m:
            traj.height = traj.height + float(height_offset_m)
            if notes is not None:
                notes.append(f"{path.name}: datum offset {float(height_offset_m):+.3f} m added to every "
                             "height")
        return traj
    if fmt == "kfgins-nav":
        traj = kfgins.read_nav(path)
        if height_offset_m:
            traj.height = traj.height + float(height_offset_m)
        return traj
    g = read_gnss(path, fmt.split(":", 1)[1], height_offset_m=height_offset_m, **gnss_options)
    if notes is not None:
        notes.extend(g.events)
    return gnss_to_trajectory(g)
