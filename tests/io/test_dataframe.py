"""to_dataframe() of the containers: the interchange columns and units."""

from __future__ import annotations

import numpy as np

from aidnav.data import GnssData, ImuData


def test_imu_and_gnss_to_dataframe():
    imu = ImuData(np.array([1.0, 2.0]), np.array([[1e-3, 2e-3, 3e-3]] * 2), np.array([[0.1, 0.2, 0.3]] * 2))
    df = imu.to_dataframe()
    assert list(df.columns) == ["time", "dtheta_x_rad", "dtheta_y_rad", "dtheta_z_rad",
                                "dv_x_m_s", "dv_y_m_s", "dv_z_m_s"]
    assert df["dtheta_z_rad"][1] == 3e-3 and df["dv_y_m_s"][0] == 0.2
    g = GnssData(np.array([1.0]), np.radians([40.0]), np.radians([-105.0]), np.array([1580.0]),
                 vel=np.array([[1.0, 2.0, np.nan]]), quality=np.array([1]))
    df = g.to_dataframe()
    assert list(df.columns) == ["time", "lat_deg", "lon_deg", "height_m", "ve", "vn", "vu", "quality"]
    np.testing.assert_allclose(df[["lat_deg", "lon_deg"]].to_numpy(), [[40.0, -105.0]], rtol=1e-15)
    assert np.isnan(df["vu"][0])
