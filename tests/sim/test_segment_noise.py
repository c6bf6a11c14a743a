"""Segment-keyed unit normals (common random numbers across trajectory variants)."""

from __future__ import annotations

import numpy as np
import pytest

from aidnav.sim import distributed_pos as dp
from aidnav.sim.scenario import parse_scenario
from aidnav.sim.segment_noise import segment_normals
from aidnav.sim.trajectory import generate_truth

INI = {"lat_deg": 40.0, "lon_deg": 116.0, "height_m": 7000.0, "speed_m_s": 100.0, "heading_deg": 40.0}


def _segs(*spec):
    out, t = [], 0.0
    for name, dur in spec:
        out.append({"name": name, "start_s": t, "end_s": t + dur})
        t += dur
    return out


def test_shared_segments_get_the_same_draws_whatever_precedes_them():
    ss = np.random.SeedSequence(5)
    a = _segs(("lead", 10.0), ("AB", 20.0), ("CD", 20.0))
    # a leg inserted, AB longer, CD shorter
    b = _segs(("lead", 10.0), ("T1", 7.0), ("AB", 30.0), ("CD", 10.0))
    ta, tb = np.arange(0.0, 50.0, 0.5), np.arange(0.0, 57.0, 0.5)
    za = segment_normals(ss, 3, ta, a, (2,))
    zb = segment_normals(ss, 3, tb, b, (2,))
    assert za.shape == (100, 2) and zb.shape == (114, 2)
    np.testing.assert_array_equal(za[:20], zb[:20])  # lead
    np.testing.assert_array_equal(za[20:60], zb[34:74])  # AB: the 40 samples of a's AB start b's 60
    np.testing.assert_array_equal(za[60:80], zb[94:114])  # CD: b's 20 samples are a's first 20
    # another stream, another seed or another segment: other draws
    assert not np.any(segment_normals(ss, 4, ta, a, (2,)) == za)
    assert not np.any(segment_normals(np.random.SeedSequence(6), 3, ta, a, (2,)) == za)
    assert not np.any(za[20:40] == za[60:80])


def test_a_name_used_twice_gets_independent_draws_and_unit_normals():
    ss = np.random.SeedSequence(7)
    segs = _segs(("S", 5000.0), ("S", 5000.0))
    z = segment_normals(ss, 0, np.arange(10000.0), segs)
    assert not np.any(z[:5000] == z[5000:])
    # 10000 unit normals: mean within 4 sd (0.04), variance within 4 sd (4·sqrt(2/N) = 0.057)
    assert abs(z.mean()) < 0.04 and abs(z.var() - 1.0) < 0.057
    assert abs(np.corrcoef(z[:-1], z[1:])[0, 1]) < 0.04
    np.testing.assert_array_equal(segment_normals(ss, 0, np.arange(3.0), None),
                                  segment_normals(ss, 0, np.arange(3.0), []))


@pytest.fixture(scope="module")
def variants():
    legs = [{"type": "straight", "duration_s": 10.0, "name": "lead"},
            {"type": "turn", "angle_deg": 9.0, "duration_s": 10.0, "name": "turn"},
            {"type": "straight", "duration_s": 20.0, "name": "AB"}]
    longer = legs[:2] + [{"type": "straight", "duration_s": 5.0, "name": "T1"}] + legs[2:]
    return [generate_truth(parse_scenario({"initial": INI, "segments": s}, "<v>")) for s in (legs, longer)]


def test_distributed_pos_runs_share_the_noise_of_shared_segments(variants):
    """An inserted 5-s leg shifts no draw of AB: the master's errors and the sub-IMU's white noise on AB
    are the same in both variants (common random numbers), and the turn-on errors too."""
    (ta, ia, sa), (tb, ib, sb) = variants
    ra = dp.simulate_distributed_pos((ta, ia, sa), seed=3)
    rb = dp.simulate_distributed_pos((tb, ib, sb), seed=3)
    ab_a = next(s for s in sa if s["name"] == "AB")["start_s"]
    ab_b = next(s for s in sb if s["name"] == "AB")["start_s"]
    ka, kb = int(round(ab_a)), int(round(ab_b))  # 1-Hz master epochs
    dva = ra.master.vel - ta.vel[ra.master.index]
    dvb = rb.master.vel - tb.vel[rb.master.index]
    # attitude errors are white: shared exactly; the velocity errors' white part too, their drift rate (a
    # continuous process, 0.0005 m/s against 0.03 m/s) differs by its history before AB
    np.testing.assert_allclose(ra.master.rph[ka:ka + 20] - ta.rph[ra.master.index][ka:ka + 20],
                               rb.master.rph[kb:kb + 20] - tb.rph[rb.master.index][kb:kb + 20], atol=1e-12)
    assert np.std(dva[ka:ka + 20] - dvb[kb:kb + 20]) < 0.1 * np.std(dva[ka:ka + 20])
    for k in ("gyro_bias", "accel_bias"):
        np.testing.assert_array_equal(ra.sub.imu_errors[k], rb.sub.imu_errors[k])
    # sub-IMU white noise on AB (100 Hz): measured − true increments agree up to the bias × dt and the
    # (different) flexure-rate history, far below the noise itself
    na = (ra.sub.imu.dv - ra.sub.imu_true.dv)[int(ab_a * 100):int(ab_a * 100) + 2000]
    nb = (rb.sub.imu.dv - rb.sub.imu_true.dv)[int(ab_b * 100):int(ab_b * 100) + 2000]
    assert np.std(na - nb) < 1e-6 * np.std(na)
