"""u-blox UBX NAV-PVT reader: logs built with pyubx2's own UBXMessage, and the real walk log."""

from __future__ import annotations

import numpy as np
import pytest
from pyubx2 import GET, UBXMessage

from aidnav.io import formats
from aidnav.io.errors import DataError
from aidnav.io.ubx import read_ubx


def pvt(sec=21, nano=749542955, itow=408639750, fix=3, ok=1, carr=2, valid=1, hacc=14, **kw):
    f = dict(iTOW=itow, year=2025, month=8, day=28, hour=17, min=30, second=sec, validDate=valid,
             validTime=valid, fullyResolved=1, tAcc=21, nano=nano, fixType=fix, gnssFixOk=ok, diffSoln=1,
             carrSoln=carr, numSV=25, lon=-105.1471665, lat=40.0966916, height=1580048, hMSL=1601435,
             hAcc=hacc, vAcc=10, velN=1000, velE=-2000, velD=-27, sAcc=70)
    f.update(kw)
    return UBXMessage("NAV", "NAV-PVT", GET, **f).serialize()


def _log(tmp_path, frames, name="log.ubx"):
    p = tmp_path / name
    p.write_bytes(b"".join(frames))
    return p


def test_nav_pvt_known_answers(tmp_path):
    """2025-08-28 17:30:21.749542955 UTC + 18 s = GPS week 2381 (from Sunday 2025-08-24),
    4 d + 17:30:39.749542955 = 408639.749542955 s; iTOW (ms) 408639750 agrees."""
    nmea = b"$GPGGA,173021.75,4005.80,N,10508.83,W,4,17,0.9,1601.4,M,-21.4,M,,*40\r\n"
    p = _log(tmp_path, [pvt(), nmea, pvt(sec=22, nano=-457045, itow=408640000, carr=1)])
    assert formats.detect_gnss_format(p) == "ubx"
    g = formats.read_gnss(p)
    assert g.week == 2381
    np.testing.assert_allclose(g.time, [408639.749542955, 408639.749542955 + 0.25], rtol=0, atol=1e-8)
    np.testing.assert_allclose(np.degrees(g.lat), 40.0966916, rtol=0, atol=1e-9)
    np.testing.assert_allclose(np.degrees(g.lon), -105.1471665, rtol=0, atol=1e-9)
    np.testing.assert_allclose(g.height, 1580.048)  # ellipsoidal 'height', not hMSL
    np.testing.assert_allclose(g.vel[0], [-2.0, 1.0, 0.027])  # velE, velN, −velD
    np.testing.assert_allclose(g.std_pos[0], [0.014, 0.014, 0.010])
    np.testing.assert_allclose(g.std_vel[0], [0.07, 0.07, 0.07])
    assert g.quality.tolist() == [1, 2]  # carrSoln fixed, float
    # NAV-PVT heights are ellipsoidal: a configured MSL offset is not applied, and a warning says so
    g2 = formats.read_gnss(p, height_offset_m=-21.4)
    assert g2.height_datum == "ellipsoid" and g2.height_offset_m == 0.0
    np.testing.assert_array_equal(g2.height, g.height)
    assert any(e.startswith("warning:") and "NOT applied" in e for e in g2.events)


def test_invalid_fixes_skipped_and_counted(tmp_path):
    p = _log(tmp_path, [pvt(fix=0, itow=408639500, sec=21, nano=-250457045), pvt(),
                        pvt(ok=0, itow=408640000, sec=22, nano=-250457045),
                        pvt(fix=2, itow=408640250, sec=22, nano=-457045), pvt(hacc=0, itow=408640500,
                                                                              sec=22, nano=499542955)])
    g = read_ubx(p)
    assert len(g) == 2
    ev = " | ".join(g.events)
    assert "fixType 0" in ev and "fixType 2" in ev and "gnssFixOK = 0" in ev
    assert g.std_pos[1, 0] == 0.05 and "NAV-PVT #5" in ev  # σ = 0 floored, the message is named


def test_itow_utc_disagreement_and_no_pvt(tmp_path):
    with pytest.raises(DataError, match="disagree"):
        read_ubx(_log(tmp_path, [pvt(itow=408650000)]))
    with pytest.raises(DataError, match="no UBX-NAV-PVT"):
        read_ubx(_log(tmp_path, [UBXMessage("NAV", "NAV-CLOCK", GET, iTOW=1).serialize()]))
    g = read_ubx(_log(tmp_path, [pvt(valid=0)]))  # no valid UTC: iTOW, week unknown
    assert g.week is None and g.time[0] == 408639.75


def test_real_walk_log_against_its_rtklib_solution(walk_dir):
    """The walk data set's .pos holds the receiver's NAV-PVT fixes with hMSL heights (its README): the
    reader must give the same positions, velocities and quality, and ellipsoidal heights = the .pos
    heights + the geoid undulation of the site (hMSL − height = 21.387 m in the first fix)."""
    d = walk_dir
    g = formats.read_gnss(d / "gnss_1730.ubx")
    p = formats.read_gnss(d / "gnss_1730_sf.pos", height_offset_m=-21.387)
    assert len(g) == len(p) == 536 and g.week == p.week == 2381
    np.testing.assert_allclose(g.time, p.time, rtol=0, atol=6e-4)  # .pos times are rounded to 1 ms
    from aidnav.nav.earth import lla_difference_enu

    de, dn, du = lla_difference_enu(g.lat, g.lon, g.height, p.lat, p.lon, p.height)
    assert np.max(np.hypot(de, dn)) < 0.01  # the .pos rounds lat/lon to 1e-7 deg (1 cm)
    assert np.max(np.abs(du)) < 0.01  # the geoid undulation varies by mm over a walk
    np.testing.assert_allclose(g.vel, p.vel, rtol=0, atol=1e-6)
    np.testing.assert_array_equal(g.quality, p.quality)
