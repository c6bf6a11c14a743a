"""Partial and optional GNSS content (issue 25 item 2): velocity per component, optional σ, σ = 0, σ < 0."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from aidnav.filters.config import LooseConfig
from aidnav.io import _std
from aidnav.io.errors import DataError
from aidnav.io.interchange import read_gnss
from aidnav.io.rtklib import read_pos

HEAD = "time,lat_deg,lon_deg,height_m"


def _csv(tmp_path, header, rows, name="g.csv"):
    p = tmp_path / name
    p.write_text(header + "\n" + "\n".join(rows) + "\n")
    return p


def test_io_defaults_are_the_filter_defaults():
    """The σ the reader names / floors to are the filter configuration's defaults (one value, two places
    that must agree: io cannot import the filters)."""
    g = LooseConfig().gnss
    assert _std.DEFAULT_POS_STD_M == tuple(g.default_pos_std_m)
    assert _std.DEFAULT_VEL_STD_M_S == tuple(g.default_vel_std_m_s)
    assert _std.ZERO_POS_STD_FLOOR_M == g.min_pos_std_m
    assert _std.ZERO_VEL_STD_FLOOR_M_S == g.min_vel_std_m_s


def test_missing_vu_column_is_not_measured(tmp_path):
    p = _csv(tmp_path, HEAD + ",ve,vn", ["1,40,116,10,1.5,-2.5", "2,40,116,10,0.5,0.25"])
    g = read_gnss(p)
    np.testing.assert_array_equal(g.vel[:, :2], [[1.5, -2.5], [0.5, 0.25]])
    assert np.isnan(g.vel[:, 2]).all()
    assert any("no vu column" in e for e in g.events)
    # σ absent: None, and the σ the filter will use is named
    assert g.std_pos is None
    assert any("default_pos_std_m" in e and "1, 1, 2 m" in e for e in g.events)


def test_vu_nan_in_some_rows_and_empty_fields(tmp_path):
    p = _csv(tmp_path, HEAD + ",ve,vn,vu", ["1,40,116,10,1,2,3", "2,40,116,10,1,2,nan", "3,40,116,10,1,2,",
                                            "4,40,116,10,,,"])
    g = read_gnss(p)
    assert g.vel[0].tolist() == [1.0, 2.0, 3.0]
    assert np.isnan(g.vel[1, 2]) and np.isnan(g.vel[2, 2]) and np.isnan(g.vel[3]).all()
    assert any("3 fix(es)" in e for e in g.events)


def test_inf_velocity_refused(tmp_path):
    p = _csv(tmp_path, HEAD + ",ve,vn,vu", ["1,40,116,10,1,2,3", "2,40,116,10,inf,2,3"])
    with pytest.raises(DataError) as ei:
        read_gnss(p)
    assert ei.value.line == 3 and "ve" in ei.value.problem


def test_zero_sigma_floored_with_warning(tmp_path):
    p = _csv(tmp_path, HEAD + ",std_e_m,std_n_m,std_u_m", ["1,40,116,10,0.5,0.5,1", "2,40,116,10,0,0.5,1"])
    g = read_gnss(p)
    assert g.std_pos[1].tolist() == [_std.ZERO_POS_STD_FLOOR_M, 0.5, 1.0]
    assert g.std_pos[0].tolist() == [0.5, 0.5, 1.0]
    w = [e for e in g.events if e.startswith("warning") and "are 0" in e]
    assert len(w) == 1 and "line 3" in w[0] and "std_e_m" in w[0] and "0.05 m" in w[0]
    g = read_gnss(p, min_pos_std_m=0.2)  # the stated floor is the one used
    assert g.std_pos[1, 0] == 0.2


@pytest.mark.parametrize("ext", ["csv", "parquet"])
def test_negative_sigma_refused_naming_line_and_column(tmp_path, ext):
    df = pd.DataFrame({"time": [1.0, 2.0, 3.0], "lat_deg": 40.0, "lon_deg": 116.0, "height_m": 10.0,
                       "ve": 0.0, "vn": 0.0, "vu": 0.0, "std_ve": [0.1, 0.1, 0.1], "std_vn": [0.1, -0.1, 0.1],
                       "std_vu": 0.2})
    p = tmp_path / f"g.{ext}"
    df.to_csv(p, index=False) if ext == "csv" else df.to_parquet(p)
    with pytest.raises(DataError) as ei:
        read_gnss(p)
    e = ei.value
    assert "std_vn" in e.problem and "negative" in e.problem and str(p) in str(e)
    assert e.line == (3 if ext == "csv" else 2)


def test_partial_sigma_columns_filled_with_defaults(tmp_path):
    p = _csv(tmp_path, HEAD + ",std_e_m,std_n_m", ["1,40,116,10,0.3,0.4", "2,40,116,10,,0.4"])
    g = read_gnss(p)
    np.testing.assert_array_equal(g.std_pos, [[0.3, 0.4, 2.0], [1.0, 0.4, 2.0]])
    assert any("missing" in e and "1, 1, 2 m" in e for e in g.events)


def test_velocity_sigma_of_unmeasured_component_may_be_missing(tmp_path):
    p = _csv(tmp_path, HEAD + ",ve,vn,std_ve,std_vn", ["1,40,116,10,1,2,0.1,0.1"])
    g = read_gnss(p)
    assert g.std_vel[0, :2].tolist() == [0.1, 0.1] and np.isnan(g.std_vel[0, 2])
    assert not any("velocity σ value(s) missing" in e for e in g.events)


_POS_HEAD = ("%  GPST            latitude(deg) longitude(deg) height(m) Q  ns  sdn(m) sde(m) sdu(m) sdne(m) "
             "sdeu(m) sdun(m) age(s) ratio\n")


def test_pos_zero_and_negative_sigma(tmp_path):
    line = "2025/07/08 19:34:{s:06.3f} 40.0966268 -105.1474483 1601.474 1 21 {sdn} 0.02 0.03 0 0 0 0 0\n"
    p = tmp_path / "s.pos"
    p.write_text(_POS_HEAD + line.format(s=18.0, sdn=0.01) + line.format(s=18.25, sdn="0.0000"))
    g = read_pos(p)
    assert g.std_pos[1, 1] == _std.ZERO_POS_STD_FLOOR_M and g.std_pos[0, 1] == 0.01
    assert any(e.startswith("warning") and "sdn(m)" in e and "line 3" in e for e in g.events)
    p.write_text(_POS_HEAD + line.format(s=18.0, sdn=0.01) + line.format(s=18.25, sdn=-0.01))
    with pytest.raises(DataError) as ei:
        read_pos(p)
    assert ei.value.line == 3 and "sdn(m)" in ei.value.problem
