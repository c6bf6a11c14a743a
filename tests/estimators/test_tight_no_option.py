"""`aidnav tight` with no option decides the NHC from the log as `aidnav process` does (issue 35 item 6,
:func:`aidnav.estimators.tight_solution.process_tight`): the simulated car of the consistency matrix is
found wheeled and gets the NHC; the same car with its IMU turned 30° in yaw against the vehicle is still
wheeled, but the tight filter has no mounting states, so it must not constrain the IMU's own forward axis
(it would pull the heading and tilt toward a wrong body axis) and says why; a configured constraints
section decides instead of the log."""

from __future__ import annotations

import numpy as np

from aidnav.data import ImuData
from aidnav.estimators.tight_solution import process_tight
from aidnav.experiments import consistency_matrix as cm
from aidnav.filters.tight import TightConfig


def _decision(run_imu, obs, eph, cfg=None):
    ev: list = []
    res, _ = process_tight(run_imu, obs, eph, cfg, events=ev)
    return [e for e in ev if e.startswith("vehicle from the log")], res


def test_no_option_decides_the_nhc_and_refuses_an_unknown_mounting():
    run, obs, eph = cm.simulate_tight(cm.condition("tight 3 satellites"), 0)
    dec, _ = _decision(run.imu, obs, eph)
    assert len(dec) == 1 and "NHC on" in dec[0], dec

    a = np.radians(30.0)  # the IMU turned 30° about its z axis against the car body
    R = np.array([[np.cos(a), np.sin(a), 0.0], [-np.sin(a), np.cos(a), 0.0], [0.0, 0.0, 1.0]])
    imu = ImuData(run.imu.time, run.imu.dtheta @ R.T, run.imu.dv @ R.T, t0=run.imu.t0)
    dec, _ = _decision(imu, obs, eph)
    assert len(dec) == 1 and "NHC off" in dec[0] and "off the IMU's forward axis" in dec[0], dec

    dec, res = _decision(run.imu, obs, eph, TightConfig(constraints={"zupt": True}))
    assert dec == []  # a constraints section: no decision, one pass
    assert len(res.time) > 0
