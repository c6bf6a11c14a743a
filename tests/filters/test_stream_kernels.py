"""The kernels of the streamed process (issue 29) against the whole-array numpy formulas they replaced:
static detection (rolling spread with running sums carried across chunks) and ``to_trajectory`` (σ,
attitude and bias columns) give the same numbers, bit for bit."""

import numpy as np
import pytest

from aidnav.data import GnssData
from aidnav.filters.config import LooseConfig
from aidnav.filters.layout import L_NINS, NAV
from aidnav.filters.preprocess import StaticDetector
from aidnav.filters.result import SENSOR_ERROR_UNITS, FilterResult, to_trajectory
from aidnav.nav.earth import radii
from aidnav.nav.rotations import quat_to_euler_batch
from aidnav.units import DEG


class _NumpyStatic:
    """The former numpy static detection (cumulative sums over the whole log, carried in the head rows)."""

    def __init__(self, det):
        self.d, self.k, self.head = det, 0, [np.zeros((1, 3)) for _ in range(4)]

    def _rolling_std(self, a, j):
        a = np.nan_to_num(a)
        h, h2 = self.head[j], self.head[j + 1]
        cs = np.vstack([h[:-1], np.cumsum(np.vstack([h[-1:], a]), axis=0)])
        cs2 = np.vstack([h2[:-1], np.cumsum(np.vstack([h2[-1:], a * a]), axis=0)])
        base = self.k - (len(h) - 1)
        idx = np.arange(self.k + 1, self.k + len(a) + 1)
        lo = np.maximum(idx - self.d.n, 0)
        cnt = (idx - lo)[:, None]
        mean = (cs[idx - base] - cs[lo - base]) / cnt
        var = (cs2[idx - base] - cs2[lo - base]) / cnt - mean**2
        self.head[j], self.head[j + 1] = cs[-(self.d.n + 1):], cs2[-(self.d.n + 1):]
        return np.sqrt(np.maximum(var, 0.0)).max(axis=1)

    def __call__(self, time, dtheta, dv, t_prev):
        c = self.d.c
        dt = np.diff(np.concatenate([[t_prev], time]))
        dt[dt <= 0] = np.nan
        with np.errstate(all="ignore"):
            ok = ((self._rolling_std(dtheta / dt[:, None], 0) < c.static_gyro_std_deg_s * DEG)
                  & (self._rolling_std(dv / dt[:, None], 2) < c.static_accel_std_m_s2))
        self.k += len(time)
        g, sp = self.d.gnss, self.d.sp
        j = np.clip(np.searchsorted(g.time, time), 0, len(g) - 1)
        jp = np.clip(j - 1, 0, len(g) - 1)
        near = (np.abs(g.time[j] - time) < 1.0) | (np.abs(g.time[jp] - time) < 1.0)
        return ok & near & (np.maximum(sp[j], sp[jp]) < c.static_gnss_speed_m_s)


@pytest.mark.parametrize("chunk", [50000, 8192, 37, 1])
def test_static_spread_as_numpy(chunk):
    rng = np.random.default_rng(0)
    n = 50000 if chunk > 1 else 3000
    t = 0.01 * np.arange(1, n + 1)
    t[1000] = t[999]
    t[2000] = t[1999] - 0.001  # Δt = 0 and < 0: rate NaN → 0
    dth = rng.normal(0, 2e-6, (n, 3)) + [0.0, 7e-7, 3e-7]
    noisy = np.where(np.arange(n) % 700 < 350, 1.0, 100.0)[:, None]  # static and moving stretches
    dv = rng.normal(0, 1e-4, (n, 3)) * noisy + [0.0, 0.0, 0.0979]
    dv[2500, 1] = np.nan  # a NaN rate counts as 0
    dth[n - 100, 2] = np.inf  # the largest float: its square overflows, no flag from here on (as numpy)
    m = int(t[-1]) + 2
    gnss = GnssData(time=np.arange(1.0, m + 1.0), lat=np.full(m, 0.5), lon=np.full(m, 2.0),
                    height=np.zeros(m), vel=rng.normal(0, 0.03, (m, 3)))
    cfg = LooseConfig()
    det = StaticDetector(gnss, cfg, 100.0)
    ref = _NumpyStatic(StaticDetector(gnss, cfg, 100.0))
    got, want, tp = [], [], 0.0
    for a in range(0, n, chunk):
        b = min(a + chunk, n)
        got.append(det(t[a:b], dth[a:b], dv[a:b], tp))
        want.append(ref(t[a:b], dth[a:b], dv[a:b], tp))
        tp = t[b - 1]
    got, want = np.concatenate(got), np.concatenate(want)
    assert 0.05 < got.mean() < 0.95  # both answers occur
    np.testing.assert_array_equal(got, want)


def _numpy_to_trajectory(res):
    """The former whole-array ``to_trajectory`` (columns only)."""
    s = res.state
    lat, h = s[:, 0], s[:, 2]
    rm, rn = radii(lat)
    pd = np.sqrt(np.maximum(res.pdiag, 0.0))
    std_pos = np.column_stack([pd[:, 7] * (rn + h) * np.cos(lat), pd[:, 6] * (rm + h), pd[:, 8]])
    rph = quat_to_euler_batch(np.ascontiguousarray(s[:, 6:10]))
    hd = rph[:, 2]
    sr = np.sqrt((np.cos(hd) * pd[:, 1]) ** 2 + (np.sin(hd) * pd[:, 0]) ** 2)
    sp = np.sqrt((np.sin(hd) * pd[:, 1]) ** 2 + (np.cos(hd) * pd[:, 0]) ** 2)
    extra = {}
    for j in range((int(res.layout[L_NINS]) - NAV) // 3):
        for i, ax in enumerate("xyz"):
            name, scale = SENSOR_ERROR_UNITS[j]
            extra[name.format(ax)] = res.bias[:, 3 * j + i] * scale
    att = np.column_stack([sr, sp, pd[:, 2]])
    return dict(rph=rph, std_pos=std_pos, std_vel=pd[:, 3:6], std_att=att), extra


def test_to_trajectory_as_numpy():
    from aidnav.filters.layout import L_N

    rng = np.random.default_rng(3)
    n = 20000
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1)[:, None]
    q[:10] = [1.0, 0.0, 0.0, 0.0]
    q[10] = [np.sqrt(0.5), np.sqrt(0.5), 0.0, 0.0]  # pitch ±90°: gimbal lock branch
    q[11] = [np.sqrt(0.5), 0.0, np.sqrt(0.5), 0.0]
    st = np.column_stack([rng.uniform(-1.5, 1.5, n), rng.uniform(-3, 3, n), rng.normal(0, 1000, n),
                          rng.normal(size=(n, 3)), q])
    pdiag = rng.normal(0, 1, (n, 18)) ** 3
    pdiag[5, 3], pdiag[6, 7], pdiag[7, 0], pdiag[8, 1], pdiag[9, 2] = np.nan, -0.0, np.inf, -np.inf, 0.0
    lay = np.full(12, -1)
    lay[L_N], lay[L_NINS] = 18, 15
    res = FilterResult(time=np.arange(float(n)), state=st, bias=rng.normal(size=(n, 9)), pdiag=pdiag,
                       node_time=np.zeros(0), layout=lay)
    with np.errstate(invalid="ignore"):
        want, want_extra = _numpy_to_trajectory(res)
    tr = to_trajectory(res)
    for k, v in want.items():
        got = getattr(tr, k)
        assert np.array_equal(got, v, equal_nan=True), k
        assert np.array_equal(np.signbit(got), np.signbit(v)), k  # −0 as numpy gives it
    assert list(tr.extra) == list(want_extra)
    for k, v in want_extra.items():
        assert np.array_equal(tr.extra[k], v), k
    for k in ("lat", "lon", "height"):
        np.testing.assert_array_equal(getattr(tr, k), st[:, {"lat": 0, "lon": 1, "height": 2}[k]])
