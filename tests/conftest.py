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
