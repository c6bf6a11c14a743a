"""The compiled loop recompiles when a model it dispatches to changes (issue 36, item 4).

numba keys a cached kernel on its own source file only: without more, the engine's loop (``run_chunk``,
in ``engine.py``) cached before a change of a model or of the model table (``measurements/``) would keep
the old one compiled in. The kernels that dispatch through ``measurements.fill`` are
``njit(cache=True, depends=MODELS_KEY)``, a hash of the measurement package's sources.

In a temporary copy of the package (with its numba cache: the loop loads from it), a loose run with a
barometer logs the barometer's innovations; then the barometer's entry in the model table's dispatch is
changed to a model that reports the height 1 m lower, and the same run, in a new process from the same
cache, must log innovations larger by exactly 1 m. Recompiling the loop takes a while: marked slow.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import aidnav

pytestmark = pytest.mark.slow

RUN = """
import json, sys
import numpy as np
from aidnav.filters import measurements as ms
from aidnav.filters.aids import aid
from aidnav.filters.engine import run_filter
from aidnav.filters.loose import run_loose
from aidnav.io.aux_sensors import BaroData
from aidnav.sim.gnss import GnssSpec, simulate_gnss
from aidnav.sim.imu import ImuSpec, corrupt_imu
from aidnav.sim.scenario import parse_scenario
from aidnav.sim.trajectory import generate_truth
from aidnav.filters.tuning import loose_config_from_specs, perturbed_initial_state

truth, imu_true, _ = generate_truth(parse_scenario(dict(
    name="s", seed=1, imu_rate_hz=50.0,
    initial=dict(lat_deg=30.0, lon_deg=114.0, height_m=50.0, speed_m_s=10.0, heading_deg=30.0),
    segments=[dict(type="straight", duration_s=20)])))
rng = np.random.default_rng(1)
spec = ImuSpec.from_units(gyro_bias_deg_h=10.0, arw_deg_sqrt_h=0.3, accel_bias_ug=1000.0, vrw_m_s_sqrt_h=0.1)
imu = corrupt_imu(imu_true, spec, rng)[0]
gs = GnssSpec(rate_hz=1.0, sigma_pos_enu=[0.5, 0.5, 1.0], sigma_vel_enu=[0.05, 0.05, 0.1])
gnss = simulate_gnss(truth, gs, rng)
k = np.arange(50, len(truth.time), 50)
baro = BaroData(truth.time[k], truth.height[k].copy(), np.full(len(k), 0.5))
lla, vel, rph = perturbed_initial_state(truth, rng)
cfg = loose_config_from_specs(spec, gs, init_rph_deg=rph, init_lla_deg_m=lla, init_vel=vel,
                              baro={"bias": False})
r = run_loose(imu, gnss, cfg, aids=[aid("baro", baro)])
inn = r.innovations
sel = inn["model"] == ms.M_BARO
stats = run_filter.stats
print(json.dumps({"nu": inn["nu"][sel, 0].tolist(), "key": ms.MODELS_KEY,
                  "misses": sum(stats.cache_misses.values()), "hits": sum(stats.cache_hits.values())}))
"""


def _run(pkg: Path) -> dict:
    env = dict(os.environ, PYTHONPATH=str(pkg), OMP_NUM_THREADS="1", AIDNAV_KERNELS="jit")
    env.pop("NUMBA_CACHE_DIR", None)
    p = subprocess.run([sys.executable, "-c", RUN], env=env, capture_output=True, text=True, cwd=pkg,
                       timeout=1200)
    assert p.returncode == 0, p.stderr
    return json.loads(p.stdout.strip().splitlines()[-1])


def test_a_changed_model_table_recompiles_the_loop(tmp_path):
    pkg = tmp_path / "pkg"
    shutil.copytree(Path(aidnav.__file__).parent, pkg / "aidnav")  # (copy2: the cache stays valid)
    before = _run(pkg)
    init = pkg / "aidnav" / "filters" / "measurements" / "__init__.py"
    text = init.read_text()
    old = "        return baro_model(nav, row, par, lay, H, z, R)\n"
    assert text.count(old) == 1
    init.write_text(text.replace(old, "        m = baro_model(nav, row, par, lay, H, z, R)\n"
                                      "        z[0] += 1.0  # the barometer reports 1 m lower\n"
                                      "        return m\n"))
    after = _run(pkg)
    assert after["key"] != before["key"]
    assert after["misses"] >= 1  # the loop was compiled again, not loaded from the stale cache
    nu0, nu1 = np.array(before["nu"]), np.array(after["nu"])
    assert len(nu0) == len(nu1) > 10
    # the first innovation is before any barometer update: the same state, exactly 1 m apart
    assert nu1[0] - nu0[0] == pytest.approx(1.0, abs=1e-9)
