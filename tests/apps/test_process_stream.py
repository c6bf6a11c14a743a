"""``aidnav process`` streamed (:mod:`aidnav.apps.process_stream`, chunks far smaller than the log) writes
what the same run with the log as one chunk (the library's in-memory :func:`aidnav.apps.process.process`)
writes, and its memory does not grow with the log (issues 29, 36)."""

from __future__ import annotations

import json
import tracemalloc

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

import aidnav.apps.process_input as pi
import aidnav.apps.process_stream as ps
from aidnav.apps.process import load_config, process, process_logs
from aidnav.io.formats import read_gnss, read_imu
from aidnav.io.interchange import read_trajectory, write_trajectory

LAT, G, OM = np.radians(30.0), 9.79, 7.292115e-5


def static_log(d, seconds, rate=100.0, seed=0, row_group=5000):
    """A level IMU at rest (gravity and the Earth rate, white noise) and 1-Hz fixes on the spot."""
    rng = np.random.default_rng(seed)
    n = int(seconds * rate)
    t = np.arange(1, n + 1) / rate
    dth = np.array([0.0, OM * np.cos(LAT), OM * np.sin(LAT)]) / rate + rng.normal(0, 1e-5, (n, 3))
    dv = np.array([0.0, 0.0, G]) / rate + rng.normal(0, 1e-4, (n, 3))
    names = ["time", "dtheta_x_rad", "dtheta_y_rad", "dtheta_z_rad", "dv_x_m_s", "dv_y_m_s", "dv_z_m_s"]
    imu = d / f"imu_{seconds}.parquet"
    pq.write_table(pa.table([t, *dth.T, *dv.T], names=names), imu, row_group_size=row_group)
    k = int(seconds)
    e = rng.normal(0, 0.5, (k, 3))
    gnss = d / f"gnss_{seconds}.csv"
    np.savetxt(gnss, np.column_stack([np.arange(1, k + 1.0), 30.0 + e[:, 1] / 111e3, 114.0 + e[:, 0] / 96e3,
                                      50.0 + e[:, 2], np.full((k, 3), 0.5), rng.normal(0, 0.02, (k, 3)),
                                      np.full((k, 3), 0.05)]), delimiter=",", fmt="%.10f",
               header="time,lat_deg,lon_deg,height_m,std_e_m,std_n_m,std_u_m,ve,vn,vu,std_ve,std_vn,std_vu",
               comments="")
    cfg = d / "static.yaml"
    cfg.write_text("imu: {arw_deg_sqrt_h: 0.1, vrw_m_s_sqrt_h: 0.05}\ngnss: {use: position}\n"
                   "init: {mode: given, lat_deg: 30.0, lon_deg: 114.0, height_m: 50.0,\n"
                   "  velocity_m_s: [0, 0, 0], roll_deg: 0, pitch_deg: 0, heading_deg: 0}\n"
                   "filter: {prop_dt_s: 0.5}\n")
    return imu, gnss, cfg


@pytest.fixture
def small_chunks(monkeypatch):
    monkeypatch.setattr(pi, "CHUNK_ROWS", 1500)


@pytest.mark.parametrize("smooth,fmt", [(False, "parquet"), (True, "csv")])
def test_streamed_job_equals_in_memory(tmp_path, small_chunks, smooth, fmt):
    imu_p, gnss_p, cfg_p = static_log(tmp_path, 120)
    out = tmp_path / "o"
    s = process_logs(imu_p, gnss_p, cfg_p, out, smooth=smooth, fmt=fmt, outages=["30:20"], figures=False)
    assert pi.open_imu(imu_p).rows == 12000 and len(next(pi.open_imu(imu_p).chunks())) == 1500  # streamed
    run = process(read_imu(imu_p), read_gnss(gnss_p), load_config(cfg_p), smooth=smooth, outages=["30:20"])
    assert run.summary["counts"]["static_samples"] > 0  # ZUPT at the static samples, flags carried
    ref = tmp_path / f"ref.{fmt}"
    write_trajectory(run.trajectory, ref)
    a, b = read_trajectory(out / f"trajectory.{fmt}"), read_trajectory(ref)
    assert len(a.time) == len(b.time) == 12000
    for k in ("time", "lat", "lon", "height", "vel", "rph", "std_pos", "std_vel", "std_att"):
        np.testing.assert_allclose(getattr(a, k), getattr(b, k), rtol=0, atol=1e-12, err_msg=k)
    for k in ("counts", "nis", "outage_score", "calibration", "gnss_position_accepted"):
        assert s[k] == json.loads(json.dumps(run.summary[k])), k
    if smooth:
        assert s["outage_score_forward"] == json.loads(json.dumps(run.summary["outage_score_forward"]))


def test_streamed_window_and_time_offset_equal_one_chunk(tmp_path, small_chunks):
    """``--start/--end`` and an IMU time offset on the chunks as they come (a window that starts and ends
    inside chunks of 1500 samples): the trajectory and summary of the log in memory as one chunk."""
    imu_p, gnss_p, cfg_p = static_log(tmp_path, 90)
    cfg = load_config(cfg_p)
    cfg = cfg.model_copy(update={"imu": cfg.imu.model_copy(update={"time_offset_s": 0.013})})
    cfg_p.write_text(cfg_p.read_text().replace("imu: {", "imu: {time_offset_s: 0.013, "))
    out = tmp_path / "o"
    s = process_logs(imu_p, gnss_p, cfg_p, out, outages=["20:10"], figures=False, start_s=17.305, end_s=71.0)
    run = process(read_imu(imu_p), read_gnss(gnss_p), cfg, outages=["20:10"], start_s=17.305, end_s=71.0)
    write_trajectory(run.trajectory, tmp_path / "ref.parquet")  # (degrees in the file: the same round trip)
    a, b = read_trajectory(out / "trajectory.parquet"), read_trajectory(tmp_path / "ref.parquet")
    assert len(a.time) == len(b.time) > 5360 and abs(a.time[0] - (17.32 + 0.013)) < 1e-9
    for k in ("time", "lat", "lon", "height", "vel", "rph", "std_pos"):
        np.testing.assert_array_equal(getattr(a, k), getattr(b, k), err_msg=k)
    for k in ("counts", "outage_score", "events", "imu_samples", "gnss_fixes"):
        assert s[k] == json.loads(json.dumps(run.summary[k])), k
    assert any("processing window" in e for e in s["events"])


def _peak_stream(d, seconds, smooth=False):
    from aidnav.filters.stream import stream_loose
    from aidnav.io.stream import iter_imu

    imu_p, gnss_p, cfg_p = static_log(d, seconds, seed=1)
    gnss, cfg = read_gnss(gnss_p), load_config(cfg_p)
    n = [0, None]

    def emit(piece, forward=False):
        n[0] += len(piece.time)
        n[1] = piece.state[-1]

    tracemalloc.start()
    tracemalloc.reset_peak()
    stream_loose(iter_imu(imu_p, 2000), gnss, cfg, emit, head_s=5.0, smooth=smooth, spool_dir=d)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return peak, n


def test_memory_does_not_grow_with_the_log(tmp_path):
    """Chunks of 2000 samples: the Python-side peak on a log 4 times longer stays within 25 % (the
    GNSS fixes and per-fix records, 1 Hz, are the only whole-log arrays), and every sample comes out."""
    p1, n1 = _peak_stream(tmp_path, 150)
    p4, n4 = _peak_stream(tmp_path, 600)
    assert n1[0] == 15000 and n4[0] == 60000
    assert abs(np.degrees(n4[1][0]) - 30.0) < 1e-4  # the static position held (≈ 10 m)
    assert p4 < 1.25 * p1


def test_streamed_bad_sample_leaves_no_file(tmp_path, small_chunks):
    """A NaN deep in the IMU file: the error names the row, and no partial trajectory is left."""
    from aidnav.io.errors import DataError

    imu_p, gnss_p, cfg_p = static_log(tmp_path, 60)
    t = pq.read_table(imu_p)
    dv = t.column("dv_y_m_s").to_numpy().copy()
    dv[4000] = np.nan
    pq.write_table(t.set_column(t.schema.get_field_index("dv_y_m_s"), "dv_y_m_s", pa.array(dv)), imu_p)
    with pytest.raises(DataError, match=r"imu_60\.parquet:4001: column dv_y_m_s: missing value or NaN"):
        process_logs(imu_p, gnss_p, cfg_p, tmp_path / "o", figures=False)
    assert not list((tmp_path / "o").glob("trajectory*"))


def test_smoother_memory_does_not_grow_with_the_nodes(tmp_path, monkeypatch):
    """With the smoother: the node matrices are on disk (read back in blocks of 64 nodes here), so the
    Python-side peak on a log 4 times longer (300 → 1200 nodes) stays within 25 % (in memory per node: its
    index, δx, ds and diag Ps; the matrices held in memory would add 3n² + n² floats, ≈ 8 MB here)."""
    import aidnav.filters.stream as fs

    monkeypatch.setattr(fs, "RTS_BLOCK", 64)
    p1, n1 = _peak_stream(tmp_path, 150, smooth=True)
    p4, n4 = _peak_stream(tmp_path, 600, smooth=True)
    assert n1[0] == 2 * 15000 and n4[0] == 2 * 60000  # forward and smoothed pieces
    assert abs(np.degrees(n4[1][0]) - 30.0) < 1e-4
    assert p4 < 1.25 * p1


def test_streamed_output_rate(tmp_path, small_chunks):
    """``--output-rate`` on the streamed path (smoothed, CSV): the in-memory job's epochs and numbers."""
    imu_p, gnss_p, cfg_p = static_log(tmp_path, 60)
    out = tmp_path / "o"
    process_logs(imu_p, gnss_p, cfg_p, out, smooth=True, fmt="csv", figures=False, output_rate_hz=10.0)
    cfg = load_config(cfg_p)
    cfg = cfg.model_copy(update={"filter": cfg.filter.model_copy(update={"output_rate_hz": 10.0})})
    run = process(read_imu(imu_p), read_gnss(gnss_p), cfg, smooth=True)
    a, b = read_trajectory(out / "trajectory.csv"), run.trajectory
    assert len(a.time) == len(b.time) == 600
    np.testing.assert_allclose(np.diff(a.time), 0.1, atol=1e-9)
    for k in ("time", "lat", "lon", "height", "vel", "rph", "std_pos"):
        np.testing.assert_allclose(getattr(a, k), getattr(b, k), rtol=0, atol=1e-12, err_msg=k)


@pytest.mark.parametrize("smooth", [False, True])
def test_background_writer_gives_the_same_file(tmp_path, small_chunks, smooth):
    """The pieces converted, checked, scored and written in the background thread: the same Parquet file,
    byte for byte, and the same summary as in the caller's thread."""
    imu_p, gnss_p, cfg_p = static_log(tmp_path, 60)
    gnss, cfg = read_gnss(gnss_p), load_config(cfg_p)
    from aidnav.io.stream import TrajectoryWriter

    got = {}
    for bg in (False, True):
        p = tmp_path / f"traj_{bg}.parquet"
        w = TrajectoryWriter(p, row_group_rows=ps.ROW_GROUP_ROWS)
        run = ps.run_process(pi.open_imu(imu_p), gnss, cfg, smooth=smooth, outages=["20:10"], write=w.write,
                             background=bg)
        w.close()
        s, dec = run.summary, run.decimated
        s.pop("timing_s")
        got[bg] = p.read_bytes(), json.dumps(s, sort_keys=True, default=str), dec.time
    assert len(read_trajectory(tmp_path / "traj_True.parquet").time) == 6000
    assert got[True][0] == got[False][0]
    assert got[True][1] == got[False][1]
    np.testing.assert_array_equal(got[True][2], got[False][2])


def test_background_writer_error_reaches_the_caller(tmp_path, small_chunks, monkeypatch):
    """A failure while writing (here the third piece) is raised by the job, and no file is left."""
    from aidnav.io.stream import TrajectoryWriter

    calls, write = [0], TrajectoryWriter.write

    def failing(self, traj):
        calls[0] += 1
        if calls[0] == 3:
            raise OSError("disk full")
        write(self, traj)

    monkeypatch.setattr(TrajectoryWriter, "write", failing)
    imu_p, gnss_p, cfg_p = static_log(tmp_path, 60)
    with pytest.raises(OSError, match="disk full"):
        process_logs(imu_p, gnss_p, cfg_p, tmp_path / "o", figures=False)
    assert calls[0] == 3  # nothing written after the failure
    assert not list((tmp_path / "o").glob("trajectory*"))


def test_trim_heap_is_harmless():
    """Giving the freed heap back (glibc's malloc_trim after the set-up; nothing elsewhere) leaves the
    process working: numpy arrays made before and after are intact."""
    from aidnav.apps.process_stream import trim_heap

    a = np.arange(1_000_000, dtype=float)
    b = [np.ones(1000) for _ in range(100)]
    del b
    trim_heap()
    assert a.sum() == 499999500000.0 and np.ones(10).sum() == 10.0


@pytest.mark.parametrize("piece", [7, 450, 5000])
def test_decimated_copy_joined_in_blocks(piece):
    """The figures' copy (the first epoch at or after each multiple of fig_dt), kept in joined blocks:
    the rows of the whole-log rule, whatever the piece size."""
    from aidnav.data import GnssData, Trajectory

    n, fig_dt = 40000, 0.37
    t = 10.0 + 0.01 * np.arange(n)
    rng = np.random.default_rng(1)
    lat, lon = 0.5 + 1e-9 * np.arange(n), 2.0 + 1e-9 * rng.normal(size=n)
    tr = Trajectory(t, lat, lon, rng.normal(size=n), rng.normal(size=(n, 3)), rng.normal(size=(n, 3)),
                    std_pos=rng.uniform(size=(n, 3)), extra={"x": np.arange(float(n))})
    gnss = GnssData(time=np.array([0.0]), lat=np.zeros(1), lon=np.zeros(1), height=np.zeros(1))
    sink = ps.Sink(gnss, np.zeros(1, bool), fig_dt)
    for a in range(0, n, piece):
        sink(ps.take_rows(tr, slice(a, min(a + piece, n))))
    b = np.floor(t / fig_dt)
    want = np.flatnonzero(np.concatenate([[True], b[1:] > b[:-1]]))
    dec = sink.decimated()
    np.testing.assert_array_equal(dec.extra["x"], want)
    np.testing.assert_array_equal(dec.std_pos, tr.std_pos[want])
    assert len(sink.dec) <= n // piece // ps.DEC_JOIN + n // ps.DEC_JOIN_ROWS + 2


def test_no_option_decision_holds_a_bounded_prefix():
    """Issue 35's no-option vehicle decision runs a first pass over the log's first ``DECIDE_SPAN_S`` only
    (issue 29: memory independent of the log's length): a 50-min log in chunks gives 20 min, cut inside a
    chunk, and the chunks after it are never read."""
    from aidnav.data import ImuData

    t = np.arange(1, 300_001) * 0.01
    read = []

    def chunks():
        for i in range(0, len(t), 20_000):
            read.append(i)
            z = np.zeros((len(t[i:i + 20_000]), 3))
            yield ImuData(t[i:i + 20_000], z, z, t0=t[i] - 0.01)

    p = ps._prefix(pi.ImuLog(chunks, (t[0], t[-1]), len(t)), ps.DECIDE_SPAN_S)
    assert p.time[0] == t[0] and ps.DECIDE_SPAN_S - 0.011 < p.time[-1] - p.time[0] <= ps.DECIDE_SPAN_S
    assert np.all(np.diff(p.time) > 0) and len(read) == 7  # 7 × 200 s chunks cover 1200 s (+ the cut one)


def test_passes_share_one_reader(tmp_path, monkeypatch):
    """Every pass over a streamed log (the checks, the first passes, the run) gets the chunks one reader
    reads (the file decoded once), the same chunks a reader of its own gives. Past SHARED_ROWS samples
    the chunks behind the passes are dropped (a pass that starts then reads the file anew), and a pass
    lagging behind one that reads on past the cap gets a reader of its own (the buffer stays bounded)."""
    import aidnav.io.stream as st

    real, opened = st.iter_imu, []

    def counting(path, rows, reader=None):
        opened.append(rows)
        return real(path, rows, reader)

    imu_p, _, _ = static_log(tmp_path, 60, row_group=2500)
    ref = list(real(imu_p, 700))  # 9 chunks (the last 400 rows)
    monkeypatch.setattr(st, "iter_imu", counting)
    monkeypatch.setattr(pi, "CHUNK_ROWS", 700)
    monkeypatch.setattr(pi, "CHECK_ROWS", 2000)
    monkeypatch.setattr(pi, "SHARED_ROWS", 3000)

    def same(got, want):
        assert len(got) == len(want)
        for a, b in zip(got, want, strict=True):
            assert a.t0 == b.t0 and all(np.array_equal(getattr(a, k), getattr(b, k)) for k in ("time", "dv"))

    log = pi.open_imu(imu_p)
    run = log.chunks()
    head = next(run)
    check = log.check_head()  # chunks 0–2 from the run's reader
    first = [c for _, c in zip(range(4), log.chunks(), strict=False)]  # 2800 rows: within the cap
    assert len(opened) == 1 and first[0] is head
    np.testing.assert_array_equal(check.time, np.concatenate([c.time for c in ref])[:2000])
    got = [head, *run]  # past the cap with no other pass: the chunks behind it dropped
    same(got, ref)
    assert len(opened) == 1 and log._chunks.__self__.rows <= 700
    same(list(log.chunks()), ref)  # the first chunks gone: a reader of its own
    assert len(opened) == 2

    log = pi.open_imu(imu_p)
    run = log.chunks()
    head = next(run)
    whole = list(log.chunks())  # reads on past the cap: the run, behind it, gets a reader of its own
    same(whole, ref)
    same([head, *run], ref)
    assert len(opened) == 4 and log._chunks.__self__.rows <= 700


def test_shared_reader_error_reaches_every_pass(tmp_path, monkeypatch):
    """A bad row found by one pass over the shared reader is the error of every pass that reaches it (no
    pass sees the log cut short there)."""
    from aidnav.io.errors import DataError

    imu_p, _, _ = static_log(tmp_path, 30)
    t = pq.read_table(imu_p)
    dv = t["dv_x_m_s"].to_numpy(zero_copy_only=False).copy()
    dv[2200] = np.nan
    bad = tmp_path / "bad.parquet"
    pq.write_table(t.set_column(t.schema.get_field_index("dv_x_m_s"), "dv_x_m_s", pa.array(dv)), bad)
    monkeypatch.setattr(pi, "CHUNK_ROWS", 700)
    log = pi.open_imu(bad)
    run = log.chunks()
    next(run)
    with pytest.raises(DataError, match="line 2201|row 2201|2201"):
        list(log.chunks())
    with pytest.raises(DataError, match="2201"):
        list(run)


def test_started_is_called_once_just_before_the_run(tmp_path, monkeypatch):
    # the aidnav command resumes its garbage collector there (console_script.resume_collections): after
    # the reading, the checks and the first passes (no configuration: the vehicle and GNSS-error passes)
    import aidnav.filters.stream as fs

    imu, gnss, _ = static_log(tmp_path, 30)
    events, run = [], fs.stream_loose

    def stream_loose(*a, **k):  # every filter pass: the first passes, then the run
        events.append("pass")
        return run(*a, **k)

    monkeypatch.setattr(fs, "stream_loose", stream_loose)
    process_logs(imu, gnss, None, tmp_path / "o", figures=False, started=lambda: events.append("started"))
    assert events.count("started") == 1 and events[-2:] == ["started", "pass"]
    assert events.count("pass") >= 2


def test_a_failure_before_the_run_leaves_no_thread(tmp_path):
    # the writer's thread starts with the run: an error in the first passes (here: ``started``) leaves no
    # thread waiting for pieces (a later fork of the figures' processes needs a process with no other thread)
    import threading

    imu, gnss, _ = static_log(tmp_path, 30)
    before = threading.active_count()

    def started():
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        process_logs(imu, gnss, None, tmp_path / "o", figures=False, started=started)
    assert threading.active_count() == before, threading.enumerate()
