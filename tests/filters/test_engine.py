"""The filter engine's shared pieces: the gate policy, the innovation log, the result type, the readers
of the odometer and barometer columns."""

from __future__ import annotations

import numpy as np
import pytest

from aidnav.filters import measurements as ms
from aidnav.filters.engine import Log, Models, Work, gated_update
from aidnav.filters.layout import L_BARO, L_N, L_ODO, layout_names, make_layout
from aidnav.io.aux_sensors import read_baro_csv, read_odometer_csv
from aidnav.io.errors import DataError


def _log(cap):
    R = ms.MAX_ROWS
    return Log(np.full(cap, np.nan), np.full(cap, -1, np.int8), np.full(cap, -1, np.int8),
               np.full(cap, np.nan), np.full((cap, R), np.nan), np.full((cap, R), np.nan),
               np.full(cap, -1, np.int64))


def test_gate_policy_rejects_then_gives_up_after_max_consecutive():
    """χ²(1) gate 9 on model 0 with max_rej 2: two outliers rejected, the third accepted ungated, then
    the counter restarts; NIS = ν²/S for one row; the state is unchanged by a rejected update."""
    n = 2
    mod = Models(np.zeros((ms.N_MODELS, 1)), np.zeros((ms.N_MODELS, ms.MAX_ROWS + 1)),
                 np.full(ms.N_MODELS, 2, np.int64), np.zeros((0, 2), np.int64))
    mod.gate[0, 1] = 9.0
    rej = np.zeros(ms.N_MODELS, np.int64)
    log = _log(5)
    P = np.eye(n)
    x = np.zeros(n)
    wk = Work(np.zeros((ms.MAX_ROWS, n)), np.zeros(ms.MAX_ROWS), np.zeros((ms.MAX_ROWS, ms.MAX_ROWS)))
    wk.H[0, 0], wk.R[0, 0] = 1.0, 1.0
    status = []
    for i, zi in enumerate([10.0, 10.0, 10.0, 10.0, 5.5]):
        wk.z[0] = zi
        x_before, P_before = x.copy(), P.copy()
        ok = gated_update(x, P, wk, 1, 0, mod, rej, log, i)
        status.append(int(log.status[i]))
        S = P_before[0, 0] + 1.0
        assert log.s[i, 0] == pytest.approx(S) and log.nu[i, 0] == pytest.approx(zi - x_before[0])
        assert log.nis[i] == pytest.approx(log.nu[i, 0] ** 2 / S)
        if not ok:
            assert np.array_equal(x, x_before) and np.array_equal(P, P_before)
    # third accepted by the rule (x → 5, P → 0.5); the fourth (ν = 5, S = 1.5, NIS 16.7) rejected again;
    # the fifth (ν = 0.5) accepted and the counter restarts
    assert status == [0, 0, 1, 0, 1] and rej[0] == 0


def test_layout_names_and_blocks():
    lay = make_layout(False, ("odometer_scale", "baro_bias"))
    assert lay[L_N] == 17 and lay[L_ODO] == 15 and lay[L_BARO] == 16
    names = layout_names(lay)
    assert len(names) == 17 and names[15] == "odometer_scale" and names[16] == "baro_bias"
    assert make_layout(True, ("clock",))[L_N] == 23
    assert len(layout_names(make_layout(True, ("lever_arm",)))) == 24
    with pytest.raises(ValueError, match="unknown calibration state"):
        make_layout(False, ("wheel",))
    with pytest.raises(ValueError, match="twice"):
        make_layout(False, ("baro_bias", "baro_bias"))


def test_aux_readers(tmp_path):
    p = tmp_path / "odo.csv"
    p.write_text("time_s,speed_km_h\n1.0,36\n1.1,72\n")
    o = read_odometer_csv(p)
    assert np.allclose(o.speed, [10.0, 20.0]) and o.std is None
    b = tmp_path / "baro.csv"
    b.write_text("time_s,height_ft,height_std_m\n1.0,100,0.5\n2.0,200,0.5\n")
    r = read_baro_csv(b)
    assert np.allclose(r.height, [30.48, 60.96]) and np.allclose(r.std, 0.5)
    bad = tmp_path / "bad.csv"
    bad.write_text("time_s,speed_m_s\n1.0,3\n1.1,x\n")
    with pytest.raises(DataError, match=r"bad.csv:3"):
        read_odometer_csv(bad)
    back = tmp_path / "back.csv"
    back.write_text("time_s,height_m\n2.0,3\n1.0,4\n")
    with pytest.raises(DataError, match="does not increase"):
        read_baro_csv(back)
    with pytest.raises(DataError, match="none of the columns"):
        read_baro_csv(p)
