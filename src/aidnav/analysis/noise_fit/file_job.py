"""``aidnav characterise``: read an IMU log, characterise it, write noise.json, imu.yaml (and allan.png).

The figure is drawn by a function the caller passes (``plot``, e.g.
:func:`aidnav.report.allan_plot.plot_allan`): analysis does not import report.
"""

from __future__ import annotations

import json
import math
import sys
import threading
from collections.abc import Callable
from pathlib import Path

import numpy as np

from aidnav.analysis.allan import allan_deviation
from aidnav.analysis.noise_fit.allan_cov import avar_cov_nb, avar_var_nb
from aidnav.analysis.noise_fit.analyse import characterise_imu, characterise_uniform
from aidnav.analysis.noise_fit.nnls import columns_nb, fit_c_nb, profile_u_nb
from aidnav.analysis.noise_fit.output import auto_grade, imu_yaml, noise_dict
from aidnav.analysis.noise_fit.prepare import uniform_interval
from aidnav.analysis.noise_fit.results import Characterisation
from aidnav.analysis.noise_fit.static import window_stats
from aidnav.analysis.noise_fit.timing import Stages
from aidnav.data import ImuData
from aidnav.io.errors import DataError
from aidnav.io.formats import detect_imu_format
from aidnav.io.interchange import read_imu
from aidnav.io.logs import read_rtklibexplorer_imu
from aidnav.io.stream import imu_time_span, iter_imu


def imu_log_format(path) -> str:
    """Format of an IMU log the characterisation reads (:func:`aidnav.io.formats.detect_imu_format`):
    "interchange" or "rtklibexplorer" (a raw log needs no ``.tag`` here: only the sample intervals
    matter). DataError when the file is missing, empty, of another or of no known format."""
    path = Path(path)
    if not path.exists():
        raise DataError(path, None, "file not found")
    fmt = detect_imu_format(path, need_time_tag=False)
    if fmt not in _READERS:
        raise DataError(path, None, f"a {fmt} log: the characterisation reads {' and '.join(_READERS)} logs")
    return fmt


#: reader of each format (increments Δθ [rad], Δv [m/s], body RFU)
_READERS: dict[str, Callable[[Path], ImuData]] = {"interchange": read_imu,
                                                  "rtklibexplorer": read_rtklibexplorer_imu}
#: how the increments of each format relate to the sensor's samples (for the vibration report): a raw
#: rtklibexplorer CSV holds point samples of the rates, read as trapezoid increments
#: (:func:`aidnav.io.logs.read_rtklibexplorer_imu`); interchange files give rates × Δt or increments as
#: they are
INCREMENT_RULE = {"interchange": "interval", "rtklibexplorer": "trapezoid"}


#: rows per batch when an interchange Parquet log is read straight into its rates (3 MB of rates; larger
#: batches hold more of the Parquet reader's buffers: 1 << 18 rows cost 60 MB more on a 10-h log)
STREAM_ROWS = 1 << 16


def _uniform_rates_streamed(path: Path):
    """(rates (M, 6) [rad/s, m/s²], dt [s], t_start [s], time of the first sample [s], the reader's events,
    an array of M + 1 values (or more) the caller may use as it likes: the intervals' memory)
    of an interchange Parquet IMU log with uniform intervals, read in batches
    (:func:`aidnav.io.stream.iter_imu`) straight into the rates: increments / their own intervals, the
    numbers :func:`uniform_rates` gives for such a log, without the whole log's increments in memory
    (and their copies). None for any other log (gaps or jitter, another format): the whole-log path."""

    span = imu_time_span(path)
    if span is None:
        return None
    chunks = iter_imu(path, STREAM_ROWS)
    rates = dt = None
    n = cap = 0
    t0 = prev = base0 = 0.0
    events: list[str] = []
    for ch in chunks:
        k = len(ch.time)
        if rates is None:
            if k < 3:
                break
            t0 = ch.t0 if ch.t0 is not None else 2 * ch.time[0] - ch.time[1]  # as uniform_rates
            step = float(np.median(np.diff(ch.time)))
            # rows of a uniform log over the span, with room: the pages never written are never mapped
            cap = int((span[1] - span[0]) / step * 1.01) + 2 * STREAM_ROWS
            rates, dt = np.empty((cap, 6)), np.empty(cap + 1)  # dt: the work array of an ADEV thread after
            prev, base0, events = t0, float(ch.time[0]), list(ch.events[1:])  # [0]: the detected format
        if n + k > cap:  # far more rows than a uniform log holds: not uniform
            rates = None
            break
        d = dt[n:n + k]
        d[0] = ch.time[0] - prev
        np.subtract(ch.time[1:], ch.time[:-1], out=d[1:])
        np.divide(ch.dtheta, d[:, None], out=rates[n:n + k, :3])
        np.divide(ch.dv, d[:, None], out=rates[n:n + k, 3:])
        prev, n = ch.time[-1], n + k
    chunks.close()
    if rates is None or n < 3:
        return None
    med = uniform_interval(dt[:n])
    if med is None:
        return None
    return rates[:n], med, float(t0), base0, events, dt


def _warm_up() -> None:
    """Import the analysis libraries and load the compiled kernels (numba's first call costs a few tenths
    of a second): run in a thread while the log is read, so that it overlaps the reading."""
    try:
        # the fit's scipy.special (~0.1 s), imported here to overlap the reading
        # lazy: scipy.special is heavy to import
        from scipy.special import digamma, gammaincinv  # noqa: F401

        tau = np.array([0.01, 0.02, 0.04])
        window_stats(np.zeros((20, 6)), 10, 2)
        avar_cov_nb(tau / 0.01, 100.0, 0.01, np.array([0.0, 1.0, 0.0, 0.0]), 1.0)
        avar_var_nb(tau / 0.01, 100.0, 0.01, np.array([0.0, 1.0, 0.0, 0.0]), 1.0)
        profile_u_nb(tau, np.zeros(3), np.ones(3), np.eye(3), np.zeros(4, np.bool_), np.zeros(4), -1.0, 1.0,
                      3, np.zeros(4), math.nan)
        fit_c_nb(columns_nb(tau, 0.0), np.zeros(3), np.ones(3), np.eye(3), np.zeros(4, np.bool_),
                  np.zeros(4), np.zeros(4), 2)
        # the ADEV kernels, on strided columns as characterise_rates gives them
        allan_deviation(np.random.default_rng(0).standard_normal((64, 2)), 100.0, workers=1)
    except Exception:  # noqa: BLE001  (a warm-up only: the analysis imports and compiles what it needs)
        pass


def characterise_file(imu_path, out_dir, static: str | None = None, grade: str | None = None,
                      timings: dict | None = None,
                      plot: Callable[[Characterisation, Path, str], Path] | None = None) -> tuple:
    """``aidnav characterise``: read any IMU log, characterise it, write noise.json, imu.yaml (and allan.png).

    static : "START:END" seconds after the first sample (either may be empty); None: the whole log (its
    longest static part when it moves: see :func:`characterise_imu`). timings : a dict that receives the
    wall time of each stage [s]. plot : ``plot(ch, path, title) -> path`` that draws the Allan deviation
    figure (:func:`aidnav.report.allan_plot.plot_allan`) into DIR/allan.png; None: no figure. A ``plot``
    with a method ``axis_done(c, axis_fit, duration_s, title)`` is told of each axis as soon as it is
    fitted (``on_axis`` of :func:`characterise_rates`; the figure's title is the one ``plot`` gets). Returns
    (Characterisation, list of written paths). Raises
    :class:`NotStaticError` / ValueError with a clear message for a moving log, bad option or unusable data.

    Speed: the analysis libraries are imported (and the compiled kernels loaded) in a thread while the
    log is read; the reader holds no reference to the log after the analysis has taken its rates. An
    interchange Parquet log with uniform intervals (and no ``static``) is read in batches straight into its
    rates (:func:`_uniform_rates_streamed`: the log's increments never are in memory whole, the same
    numbers); any other log is read whole. Fresh memory costs system time (page faults): on a 10-h log the
    peak falls from 818 to 497 MB and the system CPU from 1.6-2.3 to 0.7 s.
    """
    st = Stages(timings)
    rng = None
    if static:
        parts = static.split(":")
        try:
            if len(parts) != 2:
                raise ValueError
            rng = tuple(float(x) if x.strip() else None for x in parts)
        except ValueError:
            raise ValueError(f"--static {static!r}: expected START:END in seconds after the first sample"
                             ) from None
        if rng[0] is not None and rng[1] is not None and rng[1] <= rng[0]:
            raise ValueError(f"--static {static!r}: END must be after START")
    fmt = imu_log_format(imu_path)
    title = f"Allan deviation: {Path(imu_path).name}"
    axis_done = getattr(plot, "axis_done", None)
    on_axis = None if axis_done is None else (lambda c, a, dur: axis_done(c, a, dur, title))
    warm = threading.Thread(target=_warm_up, name="aidnav-characterise-warm-up", daemon=True)
    warm.start()
    st.lap("start")

    def release_arrow():
        pa = sys.modules.get("pyarrow")
        if pa is not None and hasattr(pa, "default_memory_pool"):  # the Parquet/CSV buffers the reader freed
            try:
                pa.default_memory_pool().release_unused()
            except AttributeError:
                pass

    def read():
        imu = _READERS[fmt](Path(imu_path))
        release_arrow()
        st.lap("read")
        warm.join()
        st.lap("imports not overlapped by the reading")
        return imu

    got = _uniform_rates_streamed(Path(imu_path)) if fmt == "interchange" and rng is None else None
    if got is not None:  # a uniform interchange Parquet log: read in batches straight into its rates
        release_arrow()
        st.lap("read")
        warm.join()
        st.lap("imports not overlapped by the reading")
        rates, dt, t_start, base0, events, work = got
        got = None
        ch = characterise_uniform(rates, dt, t_start, base0, notes=events, timings=timings, on_axis=on_axis,
                                  work=work)
        rates = work = None
    else:
        # no reference to the log is held here: characterise_imu lets it go once it has the rates
        ch = characterise_imu(read(), static=rng, increments=INCREMENT_RULE[fmt], timings=timings,
                              on_axis=on_axis)
    st.lap("characterise")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    nd = noise_dict(ch)
    nd["imu"] = str(imu_path)
    nd["grade_for_defaults"] = grade or auto_grade(ch)
    p_json = out / "noise.json"
    p_json.write_text(json.dumps(nd, indent=2, allow_nan=False))
    p_yaml = out / "imu.yaml"
    p_yaml.write_text(imu_yaml(ch, nd["grade_for_defaults"], source=str(imu_path)))
    st.lap("noise.json + imu.yaml")
    written = [p_json, p_yaml]
    if plot is not None:
        written.insert(0, plot(ch, out / "allan.png", title))
        st.lap("allan.png")
    return ch, written
