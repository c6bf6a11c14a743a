"""RTKLIB .pos reader."""

from __future__ import annotations

import numpy as np
import pytest

from aidnav.io.errors import DataError
from aidnav.io.rtklib import read_pos

HEADER = ("%  GPST            latitude(deg) longitude(deg) height(m) Q  ns  sdn(m) sde(m) sdu(m) sdne(m) "
          "sdeu(m) sdun(m) age(s) ratio vn(m/s) ve(m/s) vu(m/s) sdvn sdve sdvu sdvne sdveu sdvun\n")


def _line(t, lat=40.0966268, lon=-105.1474483, h=1601.474, q=1, vn=0.5, ve=-0.25, vu=0.125):
    #        sdn  sde  sdu                      age ratio          sdvn sdve sdvu
    return (f"{t} {lat:.7f} {lon:.7f} {h:.4f} {q} 21 0.01 0.02 0.03 0 0 0 0 0 "
            f"{vn} {ve} {vu} 0.04 0.05 0.06 0 0 0\n")


def _write(tmp_path, body, header=HEADER, name="s.pos"):
    p = tmp_path / name
    p.write_text("% program   : test\n" + header + body)
    return p


def test_columns_units_and_order(tmp_path):
    body = "".join(_line(f"2025/07/08 19:34:{18.499 + 0.25 * k:06.3f}", q=1 + (k == 2)) for k in range(4))
    g = read_pos(_write(tmp_path, body), height_offset_m=-21.4)
    assert len(g) == 4
    np.testing.assert_allclose(g.time, 243258.499 + 0.25 * np.arange(4), atol=1e-9)
    np.testing.assert_allclose(g.lat, np.radians(40.0966268))
    np.testing.assert_allclose(g.lon, np.radians(-105.1474483))
    np.testing.assert_allclose(g.height, 1601.474 - 21.4)
    np.testing.assert_allclose(g.std_pos[0], [0.02, 0.01, 0.03])  # ENU from the file's sdn sde sdu
    np.testing.assert_allclose(g.vel[0], [-0.25, 0.5, 0.125])  # ve vn vu, up positive
    np.testing.assert_allclose(g.std_vel[0], [0.05, 0.04, 0.06])
    assert g.quality.tolist() == [1, 1, 2, 1]
    assert any("week 2374" in e for e in g.events)


def test_week_tow_time_and_no_velocity(tmp_path):
    hdr = "%  GPST   latitude(deg) longitude(deg) height(m) Q ns sdn sde sdu sdne sdeu sdun age ratio\n"
    body = "".join(f"2374 {243258.5 + k:.3f} 40.0 -105.0 1600.0 5 8 1 2 3 0 0 0 0 0\n" for k in range(3))
    g = read_pos(_write(tmp_path, body, hdr))
    np.testing.assert_allclose(g.time, [243258.5, 243259.5, 243260.5])
    assert g.vel is None and g.std_vel is None and g.quality.tolist() == [5, 5, 5]


def test_malformed_middle_line_raises_with_line_number(tmp_path):
    lines = [_line(f"2025/07/08 19:34:{18.5 + k:06.3f}") for k in range(4)]
    lines[1] = lines[1].replace(" 21 ", " x ")
    p = _write(tmp_path, "".join(lines))
    with pytest.raises(DataError, match=r"s\.pos:4: not a number"):  # 2 header lines, then line 3, 4
        read_pos(p)
    lines = [_line(f"2025/07/08 19:34:{18.5 + k:06.3f}") for k in range(4)]
    lines[2] = lines[2][:40] + "\n"
    with pytest.raises(DataError, match=r"s\.pos:5: .*fields, expected 24"):
        read_pos(_write(tmp_path, "".join(lines)))


def test_truncated_last_line_is_reported(tmp_path):
    lines = [_line(f"2025/07/08 19:34:{18.5 + k:06.3f}") for k in range(4)]
    body = "".join(lines[:3]) + lines[3][:57]  # cut while writing, no line end
    g = read_pos(_write(tmp_path, body))
    assert len(g) == 3
    assert any(e.startswith("s.pos:6:") and "truncated last line (no line end)" in e for e in g.events)


def test_time_must_increase_and_gaps_are_reported(tmp_path):
    ts = [18.5, 18.75, 19.0, 19.0]
    with pytest.raises(DataError, match=r"s\.pos:6: time .* does not increase"):
        read_pos(_write(tmp_path, "".join(_line(f"2025/07/08 19:34:{t:06.3f}") for t in ts)))
    ts = [18.5, 18.75, 19.0, 25.0, 25.25]
    g = read_pos(_write(tmp_path, "".join(_line(f"2025/07/08 19:34:{t:06.3f}") for t in ts)))
    assert any(e.startswith("s.pos:6: gap of 6.000 s") for e in g.events)


def test_unsupported_formats(tmp_path):
    with pytest.raises(DataError, match="GPST"):
        read_pos(_write(tmp_path, _line("2025/07/08 19:34:18.5"), HEADER.replace("GPST", "UTC ")))
    hdr = "%  GPST   x-ecef(m) y-ecef(m) z-ecef(m) Q ns sdx sdy sdz sdxy sdyz sdzx age ratio\n"
    with pytest.raises(DataError, match="ECEF"):
        read_pos(_write(tmp_path, "2025/07/08 19:34:18.5 1 2 3 1 5 1 1 1 0 0 0 0 0\n", hdr))


# ------------------------------------------------------------------------------------- real data
def _set(data_dir, name):
    d = data_dir / name
    if not d.is_dir():
        pytest.skip(f"data set {name} not found in {data_dir}")
    return d


def test_real_drive_pos(data_dir):
    g = read_pos(_set(data_dir, "rtklibexplorer_drive_0708") / "gnss_1934_sf.pos", height_offset_m=-21.4)
    assert len(g) == 2197
    assert g.time[0] == pytest.approx(243258.499, abs=1e-9)
    assert g.time[-1] == pytest.approx(243258.499 + 0.25 * 2196, abs=1e-9)
    assert np.bincount(g.quality).tolist()[1:3] == [2189, 8]
    assert np.degrees(g.lat[0]) == pytest.approx(40.0966268, abs=1e-9)
    assert g.height[0] == pytest.approx(1601.474 - 21.4, abs=1e-9)
    np.testing.assert_allclose(g.vel[0], [-0.002, 0.010, 0.009])  # file: vn 0.010 ve -0.002 vu 0.009
    assert np.median(g.std_pos[:, 1]) == pytest.approx(0.0099, abs=1e-4)
    assert np.all(np.diff(g.time) > 0)


def test_real_walk_pos(data_dir):
    g = read_pos(_set(data_dir, "rtklibexplorer_walk_0827") / "gnss_1730_sf.pos")
    assert len(g) == 536
    counts = np.bincount(g.quality)
    assert counts[1] == 349 and counts[2] == 187
    assert g.time[0] == pytest.approx(4 * 86400 + 17 * 3600 + 30 * 60 + 39.749, abs=1e-6)  # Thursday
