"""Shared fixtures. Real data sets live outside the repository (never copied into it)."""

from __future__ import annotations

import os
import threading
import time
from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]
#: how long a thread a test started may take to end after the test before it counts as left behind [s]
THREAD_GRACE_S = 2.0


@pytest.fixture(autouse=True)
def _no_thread_left(request):
    """No test leaves a thread alive (issue 41): the figures' processes of ``process`` and ``characterise``
    are forked only from a process with no other thread, so a thread one test leaves makes every later
    test of the same (xdist) process that checks the fork fail, far from its cause. A thread the test
    started that is still alive :data:`THREAD_GRACE_S` after it fails the test that started it, named."""
    before = set(threading.enumerate())
    yield
    new = [t for t in threading.enumerate() if t not in before]
    deadline = time.monotonic() + THREAD_GRACE_S
    for t in new:
        t.join(max(0.0, deadline - time.monotonic()))
    left = [f"{t.name} (daemon {t.daemon})" for t in new if t.is_alive()]
    assert not left, f"{request.node.nodeid} left thread(s) alive: {left}"


@pytest.fixture(scope="session")
def data_dir() -> Path:
    """Directory of the real data sets: $AIDNAV_DATA, else ``../shared/data`` beside the repository.

    Skips the test when the directory is absent. Tests needing one set should check it exists, e.g.
    ``d = data_dir / "rtklibexplorer_drive_0708"; if not d.is_dir(): pytest.skip(...)``.
    """
    d = Path(os.environ.get("AIDNAV_DATA", REPO_ROOT.parent / "shared" / "data"))
    if not d.is_dir():
        pytest.skip(f"real data not found at {d} (set AIDNAV_DATA to the data directory)")
    return d


# ------------------------------------------------------------------ tight filter engine tests
def _tight_engine_args(segments, vel_noise_m_s: float = 0.0, start_error: bool = False,
                       sow: float = 400000.0):
    """A simulated tight run captured at the engine: a MEMS IMU at 50 Hz (seed 3) over ``segments``, raw GNSS
    at 2 Hz (seed 4) from a 24-satellite constellation, velocity records of the truth half-way between the
    epochs (σ 0.02 m/s, white noise of ``vel_noise_m_s`` added, seed 5), the no-configuration IMU model; the
    start at the truth or (``start_error``) 1 m north, 1 m up, 0.05 m/s and (0.1, −0.1, 0.5)° off. Returns
    (the arguments ``run_tight`` gave ``run_filter``, its result, the number of velocity records)."""
    import numpy as np  # lazy: the package's imports kept out of collection

    from aidnav.data import ImuData
    from aidnav.filters import tight as tight_module
    from aidnav.filters.config import UNKNOWN_GRADE_IMU
    from aidnav.nav.earth import radii
    from aidnav.sim.gnss_constellation import nominal_constellation
    from aidnav.sim.gnss_raw import RawGnssSpec, simulate_raw_gnss
    from aidnav.sim.imu import ImuSpec, corrupt_imu
    from aidnav.sim.scenario import parse_scenario
    from aidnav.sim.trajectory import generate_truth

    scn = parse_scenario({
        "initial": {"lat_deg": 34.2, "lon_deg": 108.9, "height_m": 500, "speed_m_s": 10, "heading_deg": 30},
        "imu_rate_hz": 50, "transition_s": 2.0, "segments": segments})
    truth, imu_true, _ = generate_truth(scn)
    imu, _ = corrupt_imu(imu_true, ImuSpec.grade("mems"), np.random.default_rng(3))
    imu = ImuData(imu.time + sow, imu.dtheta, imu.dv, t0=imu.t0 + sow)
    eph = nominal_constellation(2381, sow, 24)
    gnss = simulate_raw_gnss(truth, eph, RawGnssSpec(rate_hz=2.0), np.random.default_rng(4), sow).rover
    tv = 0.5 * (gnss.time[1:] + gnss.time[:-1])  # as the TDCP mean velocities: nodes of their own
    j = np.searchsorted(truth.time, tv - sow)
    noise = np.random.default_rng(5).normal(0.0, vel_noise_m_s, (len(j), 3)) if vel_noise_m_s else 0.0
    v = truth.vel[j] + noise
    vel = (tv, v, np.full((len(j), 3), 0.02))
    init = (sow + truth.time[0], truth.lat[0], truth.lon[0], truth.height[0], truth.vel[0], truth.rph[0])
    if start_error:
        rm = radii(truth.lat[0])[0]
        init = (init[0], init[1] + 1.0 / rm, init[2], init[3] - 1.0, init[4] + 0.05,
                init[5] + np.radians([0.1, -0.1, 0.5]))
    captured = {}

    def capture(*a):
        captured["a"] = a
        return run_filter(*a)

    run_filter = tight_module.run_filter
    mp = pytest.MonkeyPatch()
    mp.setattr(tight_module, "run_filter", capture)  # (this project's own module)
    try:
        res = tight_module.run_tight(imu, gnss, eph, tight_module.TightConfig(imu=UNKNOWN_GRADE_IMU),
                                     init_state=init, velocity_fixes=vel)
    finally:
        mp.undo()
    return captured["a"], res, len(tv)


@pytest.fixture(scope="session")
def tight_engine_args():
    """The function :func:`_tight_engine_args` (segments, …) → (run_filter's arguments, result, records)."""
    return _tight_engine_args


# ------------------------------------------------------------------ loosely coupled filter tests
def _loose_error_state(res, truth, imu_errors, idx):
    """15-state error of a loose filter result against the truth: the library's
    :func:`aidnav.analysis.errors.ins_error_state` (one definition for tests, studies and campaigns)."""
    from aidnav.analysis.errors import ins_error_state

    return ins_error_state(res, truth, imu_errors, idx)


@pytest.fixture(scope="session")
def loose_error_state():
    """The function :func:`_loose_error_state` (res, truth, imu_errors, idx) → (K, 15) errors."""
    return _loose_error_state


def _position_error_m(res, truth, idx):
    """(K, 3) ENU position error [m] (estimate − truth) and its (K, 3) 1σ from ``res.pdiag``."""
    import numpy as np

    from aidnav.nav.earth import lla_difference_enu, radii

    idx = np.asarray(idx)
    ti = np.searchsorted(truth.time, res.time[idx])
    st = res.state[idx]
    de, dn, du = lla_difference_enu(st[:, 0], st[:, 1], st[:, 2], truth.lat[ti], truth.lon[ti],
                                    truth.height[ti])
    rm, rn = radii(st[:, 0])
    pd = res.pdiag[idx]
    sig = np.sqrt(np.column_stack([pd[:, 7] * ((rn + st[:, 2]) * np.cos(st[:, 0])) ** 2,
                                   pd[:, 6] * (rm + st[:, 2]) ** 2, pd[:, 8]]))
    return np.column_stack([de, dn, du]), sig


@pytest.fixture(scope="session")
def position_error_m():
    """The function :func:`_position_error_m` (res, truth, idx) → (ENU error [m], ENU 1σ [m])."""
    return _position_error_m


# ------------------------------------------------------------------------------------------ figures
def _drawn_png(path, min_px=(300, 200), min_colour=5e-4):
    """Assert that ``path`` is a PNG figure with data drawn on it: at least ``min_px`` (width, height)
    pixels, and at least ``min_colour`` of its pixels in colour (max − min of R, G, B above 0.15: the
    data lines and markers; axes, ticks and text are grey). A blank figure or axes without data fail
    (where a file of > 1000 bytes would pass). Returns the image (H, W, channels) in [0, 1]."""
    import matplotlib.image as mpimg
    import numpy as np

    path = Path(path)
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", f"{path}: not a PNG"
    img = mpimg.imread(path)
    h, w = img.shape[:2]
    assert w >= min_px[0] and h >= min_px[1], f"{path}: {w}x{h} pixels"
    rgb = img[..., :3]
    colour = float(np.mean(rgb.max(axis=-1) - rgb.min(axis=-1) > 0.15))
    assert colour >= min_colour, f"{path}: {colour:.2%} of the pixels in colour: no data drawn"
    return img


@pytest.fixture(scope="session")
def drawn_png():
    """The function :func:`_drawn_png` (path) → image: the figure exists and has data drawn on it."""
    return _drawn_png


# ------------------------------------------------------------------ the walk data set (raw GNSS)
WALK_NAV = Path("rinex_converted") / "gnss_1730.nav"  #: the walk's RINEX navigation file, in its directory
WALK_OBS = Path("rinex_converted") / "gnss_1730.obs"  #: the walk's RINEX observations, in its directory


@pytest.fixture(scope="session")
def walk_dir(data_dir) -> Path:
    """The walk data set's directory (rtklibexplorer_walk_0827); skips when it is absent."""
    d = data_dir / "rtklibexplorer_walk_0827"
    if not d.is_dir():
        pytest.skip("walk data set not found")
    return d


def _read_walk_nav(d: Path):
    import warnings

    from aidnav.io.rinex import read_rinex_nav

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)
        return read_rinex_nav(d / WALK_NAV)


def _read_walk_gnss(d: Path):
    import warnings

    from aidnav.io.rinex import read_rinex_obs
    from aidnav.io.rtklib import read_pos

    nav = _read_walk_nav(d)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)
        obs = read_rinex_obs(d / WALK_OBS)
    return obs, nav, read_pos(d / "gnss_1730_sf.pos", height_offset_m=-21.4)


@pytest.fixture(scope="session")
def walk_nav_file(walk_dir) -> Path:
    """The walk's RINEX navigation file."""
    return walk_dir / WALK_NAV


@pytest.fixture
def walk_nav(walk_dir):
    """The walk's RINEX navigation (GpsEphemerides), read fresh for the test."""
    return _read_walk_nav(walk_dir)


@pytest.fixture(scope="session")
def load_walk_gnss(walk_dir):
    """A function ``() -> (obs, nav, ref)`` that reads the walk's RINEX observations and navigation and the
    RTK reference (with its geoid separation of the data README, −21.4 m) fresh; skips when the data set is
    absent."""
    return lambda: _read_walk_gnss(walk_dir)


@pytest.fixture(scope="session")
def load_walk(walk_dir):
    """A function ``() -> (imu, obs, nav, ref)`` that reads the walk data set fresh (the IMU log, the RINEX
    observations and navigation, the RTK reference with its geoid separation of the data README, −21.4 m),
    so that no test sees another's changes; skips when the data set is absent."""

    def load():
        from aidnav.apps.process import read_imu_any

        obs, nav, ref = _read_walk_gnss(walk_dir)
        return read_imu_any(walk_dir / "imu_1730.csv"), obs, nav, ref

    return load
