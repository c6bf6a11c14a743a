"""Issue 40 (report only): the walk with satellites removed from its RINEX observation file for 40 s
(:func:`tests.filters.test_tight_partial_sky.edit_obs`'s window, 45–85 s from the first epoch), for every
choice of the satellites dropped (3 and 2 left of the nav file's 4; the test drops G32, then G27 and G32):
the largest 3-D deviation from the full-sky run inside the window and the E/N/U 3σ coverage of it (targets:
3 satellites ≤ 10 m, 2 satellites ≤ 25 m, each covered). ``aidnav tight``'s processing with no
configuration but ``constraints: {}`` (one pass: on the walk the no-option NHC decision is "off", so the
figures are the same). ``--no-clock-from-log``: the receiver clock's prior as the grade gives it
(``gnss.clock_from_log`` off: the tree before issue 40 session 15).
"""

from __future__ import annotations

import itertools
import os
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

from aidnav.apps.process import read_imu_any
from aidnav.apps.tight import process_tight
from aidnav.filters.tight import TightConfig, to_trajectory
from aidnav.io.rinex import read_rinex_nav, read_rinex_obs
from aidnav.nav.earth import lla_difference_enu

_DATA = Path(os.environ.get("AIDNAV_DATA", Path(__file__).resolve().parents[2] / "shared" / "data"))
WALK = _DATA / "rtklibexplorer_walk_0827"
WALK_PRNS = ("G10", "G23", "G27", "G32")  # the walk's satellites with an ephemeris in its nav file
T0, T1 = 45.0, 85.0  # the window [s from the first epoch], while walking


def _edit_obs():
    """The test's RINEX editor (tests/filters/test_tight_partial_sky.py), loaded from its file."""
    import importlib.util  # lazy: only to load the test module's helper

    path = Path(__file__).resolve().parents[1] / "tests" / "filters" / "test_tight_partial_sky.py"
    sys.path.insert(0, str(path.parents[2]))
    try:
        spec = importlib.util.spec_from_file_location("_partial_sky", path)
        mod = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(mod)
    finally:
        sys.path.pop(0)
    return mod.edit_obs


def main():
    clock_from_log = "--no-clock-from-log" not in sys.argv[1:]
    cfg = TightConfig(constraints={}, gnss={"clock_from_log": clock_from_log})
    edit_obs = _edit_obs()
    src = WALK / "rinex_converted" / "gnss_1730.obs"
    imu = read_imu_any(WALK / "imu_1730.csv")
    print(f"walk {WALK}; satellites dropped for {T1 - T0:g} s; gnss.clock_from_log {clock_from_log}")
    c0 = time.process_time()
    with warnings.catch_warnings(), tempfile.TemporaryDirectory() as tmp:
        warnings.simplefilter("ignore", FutureWarning)
        nav = read_rinex_nav(WALK / "rinex_converted" / "gnss_1730.nav")
        obs = read_rinex_obs(src)
        trf = to_trajectory(process_tight(imu, obs, nav, cfg)[0])
        for k in (1, 2):
            for drop in itertools.combinations(WALK_PRNS, k):
                p = Path(tmp) / f"drop_{'_'.join(drop)}.obs"
                edit_obs(src, p, T0, T1, list(drop))
                tr = to_trajectory(process_tight(imu, read_rinex_obs(p), nav, cfg)[0])
                w = (tr.time >= obs.time[0] + T0) & (tr.time < obs.time[0] + T1)
                ref = [np.interp(tr.time[w], trf.time, a) for a in (trf.lat, trf.lon, trf.height)]
                dev = np.column_stack(lla_difference_enu(tr.lat[w], tr.lon[w], tr.height[w], *ref))
                cov = 100 * np.mean(np.abs(dev) <= 3 * tr.std_pos[w], axis=0)
                bound = 10.0 if k == 1 else 25.0
                print(f"{4 - k} left, dropped {' '.join(drop)}: largest deviation "
                      f"{np.linalg.norm(dev, axis=1).max():.2f} m (target <= {bound:g}); 3-sigma coverage "
                      f"E/N/U {' / '.join(f'{c:.0f}' for c in cov)} %", flush=True)
    print(f"CPU {time.process_time() - c0:.1f} s, load {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
