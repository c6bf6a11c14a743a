"""A partial sky in tight coupling (issue 40): the receiver-clock grade prior, the vehicle presets of
``process`` in ``tight``, heading from IMU/GNSS velocity matching, and the walk with satellites removed
from its RINEX observation file for 40 s (3, 2 and 0 satellites)."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

from aidnav.data import ImuData
from aidnav.filters.heading_match import velocity_match_heading
from aidnav.filters.tight import CLOCK_GRADES, TightConfig, apply_vehicle, clock_allan
from aidnav.sim.scenario import parse_scenario
from aidnav.sim.trajectory import generate_truth

ROOT = Path(__file__).resolve().parents[2]
WALK_PRNS = ["G10", "G23", "G27", "G32"]  # the walk's satellites with an ephemeris
T0, T1 = 45.0, 85.0  # the 40 s window (seconds from the first epoch), while walking


def test_clock_grade_prior_tcxo_by_default_and_given_coefficients_win():
    g = TightConfig().gnss
    assert g.clock_grade == "tcxo" and clock_allan(g) == CLOCK_GRADES["tcxo"] == (2e-19, 2e-20)
    assert clock_allan(TightConfig(gnss={"clock_grade": "ocxo"}).gnss) == (8e-20, 4e-23)
    assert clock_allan(TightConfig(gnss={"clock_grade": "ocxo", "clock_hm2": 1e-21}).gnss) == (8e-20, 1e-21)


def test_vehicle_presets_apply_to_the_shared_sections_and_the_config_wins():
    ev: list[str] = []
    c = apply_vehicle(TightConfig(), "car", ev)
    assert c.constraints.nhc and c.constraints.nhc_sigma_m_s == 0.05 and c.init.course_min_speed_m_s == 2.0
    assert c.imu.noise_from_static
    assert any("calibration.mounting" in e for e in ev)  # tight has no mounting states: said, not dropped
    c = apply_vehicle(TightConfig(init={"course_min_speed_m_s": 0.7}), "pedestrian")
    assert c.init.course_min_speed_m_s == 0.7 and c.constraints.zupt and not c.constraints.nhc
    assert apply_vehicle(TightConfig(), None) == TightConfig()
    with pytest.raises(ValueError, match="unknown vehicle"):
        apply_vehicle(TightConfig(), "bicycle")


@pytest.mark.parametrize("heading_deg", [30.0, 200.0])
def test_velocity_matching_recovers_the_heading_of_a_simulated_imu(heading_deg):
    """Truth IMU of a walk-like path (speed changes and turns); the heading at the start is recovered from
    noisy GNSS velocities (σ 0.1 m/s) within 3σ of its stated σ, and that σ is a few degrees."""
    scn = parse_scenario({
        "initial": {"lat_deg": 40.1, "lon_deg": -105.1, "height_m": 1600, "speed_m_s": 1.4,
                    "heading_deg": heading_deg},
        "imu_rate_hz": 100, "transition_s": 1.0,
        "segments": [{"type": "straight", "duration_s": 5},
                     {"type": "turn", "angle_deg": 90, "rate_deg_s": 30},
                     {"type": "straight", "duration_s": 5},
                     {"type": "turn", "angle_deg": -120, "rate_deg_s": 40},
                     {"type": "straight", "duration_s": 5},
                     {"type": "turn", "angle_deg": 180, "rate_deg_s": 45},
                     {"type": "straight", "duration_s": 5}]})
    truth, imu_true, _ = generate_truth(scn)
    imu = ImuData(imu_true.time, imu_true.dtheta, imu_true.dv, t0=imu_true.t0)
    rng = np.random.default_rng(7)
    tg = np.arange(truth.time[0], truth.time[-1], 0.25)
    vg = np.column_stack([np.interp(tg, truth.time, truth.vel[:, i]) for i in range(3)])
    vg += rng.normal(0, 0.1, vg.shape)
    r, p = truth.rph[0, 0], truth.rph[0, 1]
    psi, sig, n = velocity_match_heading(imu, float(imu.t0), r, p, tg, vg)
    err = np.degrees(np.angle(np.exp(1j * (psi - truth.rph[0, 2]))))
    assert n >= 5 and np.degrees(sig) < 5.0
    assert abs(err) < 3 * np.degrees(sig) + 0.5, (err, np.degrees(sig))


def test_velocity_matching_removes_a_known_gyro_bias():
    """A consumer gyro's bias (0.15 deg/s per axis, ~540 deg/h) on the simulated IMU of a car that starts
    with a straight acceleration: the level frame tilts by g·bias·t and gravity leaks into the horizontal
    velocity changes, so without the bias the matched heading is off by more than 3σ + 1°; with the bias
    measured at rest (``gyro_bias``, what ``aidnav tight`` passes: the mean rate of the static levelling
    run) it is within 3σ + 0.5°. Measured: 87.1° off at σ 3.0° without, 0.98° at σ 0.85° with."""
    scn = parse_scenario({
        "initial": {"lat_deg": 40.0, "lon_deg": 116.0, "height_m": 50, "speed_m_s": 0.0, "heading_deg": 20.0},
        "imu_rate_hz": 100, "transition_s": 1.0,
        "segments": [{"type": "static", "duration_s": 30},
                     {"type": "accelerate", "duration_s": 10, "to_speed_m_s": 10},
                     {"type": "straight", "duration_s": 30},
                     {"type": "turn", "angle_deg": 90, "duration_s": 15},
                     {"type": "straight", "duration_s": 10}]})
    truth, imu_true, _ = generate_truth(scn)
    b = np.radians([0.15, -0.15, 0.15])
    dt = np.diff(np.concatenate([[imu_true.t0], imu_true.time]))
    imu = ImuData(imu_true.time, imu_true.dtheta + b * dt[:, None], imu_true.dv, t0=imu_true.t0)
    tg = np.arange(truth.time[0], truth.time[-1], 1.0)
    vg = np.column_stack([np.interp(tg, truth.time, truth.vel[:, i]) for i in range(3)])
    vg += np.random.default_rng(3).normal(0, 0.05, vg.shape)
    r, p = truth.rph[0, 0], truth.rph[0, 1]
    err = {}
    for name, gb in (("without", None), ("with", b)):
        psi, sig, _ = velocity_match_heading(imu, float(imu.t0), r, p, tg, vg, gyro_bias=gb)
        err[name] = (abs(np.degrees(np.angle(np.exp(1j * (psi - truth.rph[0, 2]))))), np.degrees(sig))
    assert err["with"][0] < 3 * err["with"][1] + 0.5, err
    assert err["without"][0] > 3 * err["without"][1] + 1.0, err


# ------------------------------------------------------------------ the walk, satellites removed
def edit_obs(src: Path, dst: Path, t0: float, t1: float, drop: list[str]) -> None:
    """Copy a RINEX 3 observation file without the satellites ``drop`` at the epochs t0 ≤ t − t_first < t1
    (the epoch line's satellite count rewritten)."""
    lines = src.read_text().splitlines(keepends=True)
    i = next(k for k, ln in enumerate(lines) if "END OF HEADER" in ln) + 1
    out, first = lines[:i], None
    while i < len(lines):
        ln = lines[i]
        if not ln.startswith(">"):
            out.append(ln)
            i += 1
            continue
        n = int(ln[32:35])
        f = ln.split()
        sec = int(f[4]) * 3600 + int(f[5]) * 60 + float(f[6])
        first = sec if first is None else first
        sats = lines[i + 1:i + 1 + n]
        if t0 <= sec - first < t1:
            sats = [s for s in sats if s[:3] not in drop]
        out += [ln[:32] + f"{len(sats):3d}" + ln[35:], *sats]
        i += 1 + n
    dst.write_text("".join(out))


@pytest.fixture(scope="module")
def walk_partial(data_dir, tmp_path_factory):
    """`aidnav tight` with no configuration (issue 40's acceptance): full-sky run and runs with 3, 2, 0
    satellites in the window: per case the ENU deviation from the full-sky solution and its σ at the
    output samples inside the window, and the pseudoranges used."""
    d = data_dir / "rtklibexplorer_walk_0827"
    if not d.is_dir():
        pytest.skip("walk data set not found")
    from aidnav.apps.process import read_imu_any
    from aidnav.apps.tight import process_tight
    from aidnav.filters.tight import to_trajectory
    from aidnav.io.rinex import read_rinex_nav, read_rinex_obs
    from aidnav.nav.earth import lla_difference_enu

    cfg = None  # no configuration: the unknown-grade IMU model (config.UNKNOWN_GRADE_IMU)
    src = d / "rinex_converted" / "gnss_1730.obs"
    imu = read_imu_any(d / "imu_1730.csv")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)
        nav = read_rinex_nav(d / "rinex_converted" / "gnss_1730.nav")

        def run(path):
            obs = read_rinex_obs(path)
            res, _ = process_tight(imu, obs, nav, cfg)
            return res, obs

        full, obs = run(src)
        trf = to_trajectory(full)
        out = {}
        tmp = tmp_path_factory.mktemp("walk_obs")
        for keep in (3, 2, 0):
            p = tmp / f"keep{keep}.obs"
            edit_obs(src, p, T0, T1, WALK_PRNS[keep:])
            res, _ = run(p)
            tr = to_trajectory(res)
            w = (tr.time >= obs.time[0] + T0) & (tr.time < obs.time[0] + T1)
            de, dn, du = lla_difference_enu(
                tr.lat[w], tr.lon[w], tr.height[w], np.interp(tr.time[w], trf.time, trf.lat),
                np.interp(tr.time[w], trf.time, trf.lon), np.interp(tr.time[w], trf.time, trf.height))
            ge = res.epochs
            in_w = (ge["time"] >= obs.time[0] + T0) & (ge["time"] < obs.time[0] + T1)
            out[keep] = (np.column_stack([de, dn, du]), tr.std_pos[w], int(ge["n_pr"][in_w].max()))
    return out


def test_walk_three_and_two_satellites_stay_within_their_3_sigma(walk_partial):
    for keep in (3, 2):
        dev, sig, npr = walk_partial[keep]
        assert npr == keep
        assert np.all(np.abs(dev) <= 3 * sig), keep


def test_walk_two_satellites_within_25_m(walk_partial):
    """No configuration: measured 9.1 m with the TDCP velocity records (7.7 m with the TDCP rows; 27.7 m
    with the 15-state default IMU model before issue 40's session 9); 9.1 m with the levelled start tilt
    correlated with the accelerometer states (session 12, n35t; 9.0 m without on the same tree); 9.70 m in
    session 13. Session 15 (r40p): **22.98 m** (N −21.6 m at σ_N 19.9 m, covered) with the receiver
    clock's drift wander measured on the log (``gnss.clock_from_log``): with the TCXO prior the clock's
    wrong prediction held the position along the direction two satellites leave free, by chance (with the
    walk's clock ramp removed from the observations and the TCXO prior, 29.0 m); now that direction is the
    IMU's alone, as with none (free inertia, 51.7 m)."""
    dev, _, _ = walk_partial[2]
    assert np.linalg.norm(dev, axis=1).max() <= 25.0


def test_walk_three_satellites_within_10_m(walk_partial):
    """The issue's bound on the largest deviation from the full-sky solution with 3 satellites for 40 s, and
    its 3σ covering it. Measured 9.2 m with the TDCP velocity records in session 9 (27.6 m before), 8.8 m in
    session 12, 10.08 m since the tilt turns at every moving node's heading correction (session 13, p35p;
    a strict xfail then, with a guard at 10.5 m). Session 15 (r40p): **8.53 m** (E/N/U RMS(dev)/RMS(σ) 0.12 /
    0.53 / 0.31) — the walk's receiver clock ramps its drift by −0.2 m/s² (8 m/s over the window) against
    the TCXO prior's 1.2 m/s σ over 40 s, and with three satellites the clock's wrong prediction went into
    the position along the direction they leave free; ``gnss.clock_from_log`` raises the drift's random walk
    to the wander the log's SPP drifts show (h-2 5.2e-19, 26× the TCXO's). The sky scored: the RINEX
    navigation file alone (G10, G23, G27, G32), as the fixture reads it — not ``aidnav tight``'s default,
    which adds the UBX log's Galileo and GPS CNAV ephemerides."""
    dev, sig, _ = walk_partial[3]
    assert np.linalg.norm(dev, axis=1).max() <= 10.0
    assert np.all(np.mean(np.abs(dev) <= 3 * sig, axis=0) >= 0.95)


def test_walk_no_satellites_3_sigma_coverage(walk_partial):
    """Issue 35: free inertia for 40 s covered by its 3σ on every axis (measured 100 %: 43.9 m against a
    σ_h up to 28 m with the velocity records, 43.9 m with the TDCP rows; 51 % east coverage before
    session 9, the noise model then not raised to the log's static samples)."""
    dev, sig, npr = walk_partial[0]
    assert npr == 0
    assert np.all(np.mean(np.abs(dev) <= 3 * sig, axis=0) >= 0.95)


def test_no_configuration_is_the_unknown_grade_imu_model_under_every_preset():
    """No imu section: the unknown-grade IMU model (Groves' consumer row, config.UNKNOWN_GRADE_IMU) with
    its scale-factor and misalignment states (27 INS states); the car preset keeps it (noise from the static
    samples included); a preset without the NHC (pedestrian, aircraft, ship) takes the accelerometer
    misalignment as states too (33; issue 35 session 16), and so does the car with the NHC turned off, while
    a pedestrian given the NHC keeps 27; an imu section is the user's model (the field defaults under its
    keys)."""
    from aidnav.filters.config import UNKNOWN_GRADE_IMU, UNKNOWN_GRADE_IMU_ACCEL_MISALIGNMENT, ImuNoise

    unknown = ImuNoise(**UNKNOWN_GRADE_IMU)
    free = ImuNoise(**UNKNOWN_GRADE_IMU_ACCEL_MISALIGNMENT)
    assert TightConfig().imu == unknown and TightConfig().nins == 27
    assert apply_vehicle(TightConfig(), "car").imu == unknown
    for name in ("pedestrian", "aircraft", "ship"):
        c = apply_vehicle(TightConfig(), name)
        assert c.imu == free and c.nins == 33
    # the folded σ is the bias ⊕ m·g (the same row's 10 mg, 0.5 mg, 0.5°): unfolded, m·g leaves it
    assert free.accel_bias_sigma_ug == pytest.approx(np.sqrt(unknown.accel_bias_sigma_ug ** 2
                                                             - (np.radians(0.5) * 1e6) ** 2))
    assert apply_vehicle(TightConfig(constraints={"nhc": False}), "car").imu == free
    assert apply_vehicle(TightConfig(constraints={"nhc": True}), "pedestrian").imu == unknown
    own = TightConfig(imu={"gyro_bias_sigma_deg_h": 10.0})
    ped = apply_vehicle(own, "pedestrian").imu
    assert own.nins == 15 and ped.gyro_bias_sigma_deg_h == 10.0 and not ped.scale_factors
    assert TightConfig(states=11).nins == 9


# ------------------------------------------------------------------ the walk, no configuration
def _walk_run(data_dir, load_walk, cfg):
    """`aidnav tight`'s processing with ``cfg``: ENU errors against the RTK reference at every reference
    epoch, their σ, and the summary of the run."""
    from aidnav.apps.tight import process_tight
    from aidnav.filters.tight import to_trajectory
    from aidnav.nav.earth import lla_difference_enu

    imu, obs, nav, ref = load_walk()
    d = data_dir / "rtklibexplorer_walk_0827"
    ev: list[str] = []
    res, _ = process_tight(imu, obs, nav, cfg, events=ev)
    tr = to_trajectory(res)
    sel = (ref.time >= tr.time[0]) & (ref.time <= tr.time[-1])
    j = np.clip(np.searchsorted(tr.time, ref.time[sel]), 0, len(tr.time) - 1)
    de, dn, du = lla_difference_enu(tr.lat[j], tr.lon[j], tr.height[j], ref.lat[sel], ref.lon[sel],
                                    ref.height[sel])
    return np.column_stack([de, dn, du]), tr.std_pos[j], res, ev, (ref, obs, nav, d)


@pytest.fixture(scope="module")
def walk_default(data_dir, load_walk):
    """No configuration (the carrier phase as TDCP velocity records, ``gnss.tdcp_model`` 'velocity')."""
    return _walk_run(data_dir, load_walk, None)


@pytest.fixture(scope="module")
def walk_rows(data_dir, load_walk):
    """The carrier phase as TDCP delta-range rows (``gnss.tdcp_model: rows``), nothing else configured."""
    return _walk_run(data_dir, load_walk, TightConfig(gnss={"tdcp_model": "rows"}))


def _vel_rms_h(res, ref):
    """Horizontal RMS [m/s] of the filter's mean velocity over each interval of the RTK reference whose
    ends are both fixed (Q = 1) against the RTK positions' difference over it: the mean velocity over the
    interval by definition, so no time-tag convention enters (:mod:`aidnav.analysis.velocity_reference`).
    The reference file's own velocity is not used: it is the u-blox receiver's NAV-PVT velocity, 0.13 s
    late on its positions (``test_walk_reference_velocity_is_late_on_its_own_positions``)."""
    from aidnav.analysis.velocity_reference import interval_velocity_errors

    iv = interval_velocity_errors(res.time, res.state[:, 3:6], ref.time, ref.lat, ref.lon, ref.height,
                                  use=ref.quality == 1)
    assert len(iv) > 300
    return iv.rms_horizontal()


def test_walk_reference_velocity_is_late_on_its_own_positions(data_dir):
    """The walk's ``gnss_1730_sf.pos`` is the receiver's UBX-NAV-PVT (lat, lon, hMSL, velN/E/D, carrSoln,
    numSV, hAcc/√2, sAcc/√2, checked field by field: results.md, issue 40 session 11): its velocity comes out
    of the u-blox navigation filter late on its positions — measured 0.134 s (the loose filter's velocity
    delay state on the same file: 0.135 ± 0.003 s; the drive log of the same receiver: 0.13 s) — so scoring
    a velocity against it at its stamps charges the reference's lag to the estimate."""
    from aidnav.analysis.velocity_reference import velocity_lateness
    from aidnav.io.rtklib import read_pos

    d = data_dir / "rtklibexplorer_walk_0827"
    if not d.is_dir():
        pytest.skip("walk data set not found")
    ref = read_pos(d / "gnss_1730_sf.pos", height_offset_m=-21.4)
    lag, _ = velocity_lateness(ref.time, ref.vel, ref.time, ref.lat, ref.lon, ref.height,
                               use=ref.quality == 1)
    assert 0.10 <= lag <= 0.16, lag


def test_walk_tight_velocity_is_on_the_positions_time(walk_default):
    """aidnav's velocity (IMU + Doppler + phase) against the same positions: measured 0.021 s late — the
    IMU's stamps: the loose filter's time-offset state on the walk gives −0.028 ± 0.002 s, and ``aidnav
    tight`` estimates no time offset — not the reference velocity's 0.13 s."""
    from aidnav.analysis.velocity_reference import velocity_lateness

    _, _, res, _, (ref, *_rest) = walk_default
    lag, _ = velocity_lateness(res.time, res.state[:, 3:6], ref.time, ref.lat, ref.lon, ref.height,
                               use=ref.quality == 1)
    assert abs(lag) <= 0.05, lag


def test_walk_velocity_with_and_without_the_carrier_phase(walk_default):
    """Horizontal mean-velocity RMS against the RTK positions' differences (``_vel_rms_h``), no
    configuration: measured 0.077 m/s with the TDCP velocity records, 0.125 m/s without the phase (code +
    Doppler); against the reference file's velocity at its stamps (the figure before session 11) 0.137 and
    0.160 m/s."""
    from aidnav.apps.process import read_imu_any
    from aidnav.apps.tight import process_tight

    _, _, res, _, (ref, obs, nav, d) = walk_default
    cfg = TightConfig(gnss={"use_phase": False})
    res0, _ = process_tight(read_imu_any(d / "imu_1730.csv"), obs, nav, cfg)
    assert res0.counts["velocity_records"] == 0 and res0.counts["tdcp_used"] == 0
    assert _vel_rms_h(res, ref) < 0.75 * _vel_rms_h(res0, ref)


def test_walk_tdcp_rows_velocity_as_good_as_the_records(walk_rows, walk_default):
    """The TDCP delta-range rows: measured 0.077 m/s (as the records: 0.077 m/s), 1,902 rows used and 13
    gated."""
    _, _, res, _, (ref, *_rest) = walk_rows
    assert res.counts["tdcp_used"] > 1500 and res.counts["velocity_used"] == 0
    assert _vel_rms_h(res, ref) <= 1.05 * _vel_rms_h(walk_default[2], ref)


@pytest.mark.xfail(strict=True, reason="issue 40 target not reached: 0.077 m/s measured against the RTK "
                   "positions' differences (0.125 m/s without the phase; 0.074 m/s with the IMU time offset "
                   "the loose filter estimates, -0.028 s; 0.068 m/s smoothed); the TDCP least-squares mean "
                   "velocity of the 4 satellites itself scores 0.090 m/s (results.md, issue 40 session 11); "
                   "the receiver wind-up moves it to 0.0766 m/s, the SBAS phase (gnss.systems GECRS) to "
                   "0.0925 m/s (0.0751 with the rows' phase weights); every lever at once 0.071 m/s "
                   "(results.md, issue 40 session 13); with the UBX log (the default) and the receiver's "
                   "phase sigma 0.0675 m/s, while the reference's own noise (three-cornered hat) puts a "
                   "perfect estimate at about 0.049 m/s against these differences (results.md, issue 40 "
                   "session 15)")
def test_walk_velocity_within_5_cm_s(walk_default):
    _, _, res, _, (ref, *_rest) = walk_default
    assert _vel_rms_h(res, ref) <= 0.05


def test_walk_default_vertical_and_coverage(walk_default):
    """No config: RTKLIB's default ionosphere, heading from velocity matching, TDCP velocities; vertical
    RMS ≤ 3.5 m (measured 2.98 m with the unknown-grade IMU model of session 9, 2.84 m with the 15-state
    model before; 6.84 m before the ionospheric fallback) and 3σ coverage ≥ 95 % per axis (measured
    100 %)."""
    d, s, res, ev, _ = walk_default
    assert len(d) > 500
    assert np.sqrt(np.mean(d[:, 2] ** 2)) <= 3.5
    assert np.all(np.mean(np.abs(d) <= 3 * s, axis=0) >= 0.95)
    assert "default coefficients" in res.iono_model
    assert any("matching IMU and SPP velocity" in e for e in ev)
    assert res.counts["velocity_used"] > 300  # TDCP velocity records accepted by the filter


def test_walk_default_horizontal_rms_at_most_rtklib_spp(walk_default):
    """Measured 8.45 m with the carrier phase and the unknown-grade IMU model (8.37 m with the 15-state
    model before session 9; aidnav's SPP 8.51 m, RTKLIB's 8.50 m)."""
    d = walk_default[0]
    assert np.sqrt(np.mean(d[:, 0] ** 2 + d[:, 1] ** 2)) <= 8.50


def test_walk_tdcp_rows_coverage_and_horizontal(walk_rows):
    """The TDCP rows: 3σ coverage ≥ 95 % per axis (measured 100 %), horizontal RMS ≤ RTKLIB SPP's 8.50 m
    (measured 8.05 m)."""
    d, s, *_ = walk_rows
    assert np.all(np.mean(np.abs(d) <= 3 * s, axis=0) >= 0.95)
    assert np.sqrt(np.mean(d[:, 0] ** 2 + d[:, 1] ** 2)) <= 8.50


@pytest.mark.xfail(strict=True, reason="why the rows are not the default: 4.18 m measured (mean +4.11 m: the "
                   "phase ties the track to the start's code error and it rises 0.84 m in 134 s; TDCP vs RTK "
                   "height changes +3.1 ± 49 mm per interval against a σ_φ of 5 mm)")
def test_walk_tdcp_rows_vertical_within_3_5_m(walk_rows):
    d = walk_rows[0]
    assert np.sqrt(np.mean(d[:, 2] ** 2)) <= 3.5


def test_summary_states_the_ionosphere_and_a_bad_vehicle_exits_2(tmp_path):
    from typer.testing import CliRunner

    from aidnav.apps.tight import format_tight_summary
    from aidnav.cli import app

    txt = format_tight_summary({"imu": "i", "obs": "o", "nav": "n", "output": "t", "states": 17,
                                "ionosphere": "Klobuchar (default coefficients), sigma 50 % of the delay",
                                "events": []})
    assert "ionosphere: Klobuchar (default coefficients), sigma 50 % of the delay" in txt
    r = CliRunner().invoke(app, ["tight", "--imu", str(tmp_path / "i.csv"), "--obs", str(tmp_path / "o.obs"),
                                 "--nav", str(tmp_path / "n.nav"), "--vehicle", "bicycle", "-o",
                                 str(tmp_path / "out")])
    assert r.exit_code == 2 and "unknown vehicle" in r.output


def test_nhc_in_tight_bounds_a_car_without_satellites():
    """The car preset's non-holonomic constraint in the tight filter (simulated car, MEMS IMU, GNSS gone
    for the last 60 s): NHC updates happen and the cross-track/vertical drift is smaller with it than
    free inertial from the same state (same IMU, GNSS and initial errors)."""
    from aidnav.filters.tight import run_tight
    from aidnav.filters.tuning import loose_config_from_specs
    from aidnav.nav.earth import lla_difference_enu
    from aidnav.sim.gnss_constellation import nominal_constellation
    from aidnav.sim.gnss_raw import RawGnssSpec, limit_satellites, simulate_raw_gnss
    from aidnav.sim.imu import ImuSpec, corrupt_imu

    sow = 400000.0
    scn = parse_scenario({"initial": {"lat_deg": 34.2, "lon_deg": 108.9, "height_m": 500, "speed_m_s": 15,
                                      "heading_deg": 30}, "imu_rate_hz": 50, "transition_s": 2.0,
                          "segments": [{"type": "straight", "duration_s": 60},
                                       {"type": "turn", "angle_deg": 90, "rate_deg_s": 6},
                                       {"type": "straight", "duration_s": 45}]})
    truth, imu_true, _ = generate_truth(scn)
    eph = nominal_constellation(2381, sow, 24)
    spec = ImuSpec.grade("mems")
    rng = np.random.default_rng(11)
    imu_c, _ = corrupt_imu(imu_true, spec, rng)
    imu = ImuData(imu_c.time + sow, imu_c.dtheta, imu_c.dv, t0=imu_c.t0 + sow)
    gspec = RawGnssSpec(rate_hz=1.0)
    eph.iono_alpha, eph.iono_beta = gspec.iono_alpha, gspec.iono_beta
    sim = simulate_raw_gnss(truth, eph, gspec, rng, sow)
    none = limit_satellites(sim.rover, sim.truth["elevation"], [(60.0, 1e4, 0)], sow + truth.time[0])
    init = (sow + truth.time[0], truth.lat[0], truth.lon[0], truth.height[0], truth.vel[0], truth.rph[0])
    base = dict(imu=loose_config_from_specs(spec).imu, init={"attitude_sigma_deg": (0.2, 0.2, 1.0),
                "position_sigma_m": (1, 1, 1), "velocity_sigma_m_s": (0.1, 0.1, 0.1)},
                gnss={"mask_deg": 5.0, "range_errors": False})
    cfg_free = TightConfig(**base, constraints={"zupt": False})
    cfg_nhc = apply_vehicle(TightConfig(**base, constraints={"zupt": False}), "car")
    assert cfg_nhc.constraints.nhc
    end = {}
    for name, cfg in (("free", cfg_free), ("nhc", cfg_nhc)):
        res = run_tight(imu, none, eph, cfg, init_state=init)
        j = np.clip(np.searchsorted(truth.time, res.time[-1] - sow - 1e-9), 0, len(truth.time) - 1)
        s = res.state[-1]
        end[name] = np.linalg.norm(lla_difference_enu(s[0], s[1], s[2], truth.lat[j], truth.lon[j],
                                                      truth.height[j]))
        if name == "nhc":
            assert res.counts["nhc_updates"] >= 100  # one per node (1 s) over the 120 s
        else:
            assert res.counts["nhc_updates"] == 0
    assert end["nhc"] < 0.5 * end["free"], end  # measured 5.2 m vs 44.1 m


def test_walk_injected_cycle_slip_does_not_move_the_solution(walk_default):
    """A one-cycle slip injected into G23's phase halfway through the walk: caught (phase-Doppler test),
    that satellite's TDCP row of the interval is not formed, and the tight solution moves by less than its
    σ."""
    from aidnav.apps.process import read_imu_any
    from aidnav.apps.tight import process_tight
    from aidnav.filters.tight import to_trajectory
    from aidnav.nav.earth import lla_difference_enu

    _, _, res, ev, (_, obs, nav, d) = walk_default
    o2 = obs.subset_sats(obs.prn)
    j = int(np.flatnonzero(obs.prn == 23)[0])
    k = len(obs.time) // 2
    assert np.isfinite(o2.phase1[k - 1:k + 1, j]).all()
    o2.phase1[k:, j] += 1.0
    ev2: list[str] = []
    res2, _ = process_tight(read_imu_any(d / "imu_1730.csv"), o2, nav, None, events=ev2)
    n_slip = [int(e.split("; ")[1].split()[0]) for e in ev + ev2 if e.startswith("carrier phase")]
    assert n_slip[1] == n_slip[0] + 1
    a, b = to_trajectory(res), to_trajectory(res2)
    de, dn, du = lla_difference_enu(b.lat, b.lon, b.height, a.lat, a.lon, a.height)
    assert np.all(np.abs(np.column_stack([de, dn, du])) <= a.std_pos)
    assert np.all(np.abs(b.vel - a.vel) <= a.std_vel)


def test_walk_receiver_windup_is_common_to_the_satellites(walk_default):
    """The receiver phase wind-up of the walk's hand-held antenna (antenna = body frame, the forward tight
    attitude at each epoch; :func:`aidnav.estimators.tdcp.windup_increments`): its increments are mm per
    interval (measured 5.2 mm RMS), but the part that differs between satellites — all the velocity can see;
    the common part is the clock's — is below a millimetre (measured 0.30 mm RMS: the antenna is held within
    ~5° of level, so the turns are about its boresight), and the TDCP mean velocities with and without it
    differ by < 5 mm/s RMS (results.md, issue 40 session 13: the filter's 0.0767 → 0.0766 m/s)."""
    from aidnav.estimators.dgps import spp_series
    from aidnav.estimators.tdcp import tdcp_series
    from aidnav.nav.earth import dcm_ecef_to_enu
    from aidnav.nav.rotations import dcm_from_quat

    _, _, res, _, (ref, obs, nav, _d) = walk_default
    k = np.clip(np.searchsorted(res.time, obs.time), 0, len(res.time) - 1)
    c_ne = dcm_ecef_to_enu(ref.lat[0], ref.lon[0]).T
    att = np.array([c_ne @ dcm_from_quat(res.state[i, 6:10]) for i in k])
    sp = spp_series(obs, nav)
    r0 = tdcp_series(obs, nav, sp["ecef"])
    r1 = tdcp_series(obs, nav, sp["ecef"], attitude=att)
    w = r1["windup"][np.isfinite(r1["windup"]).any(axis=1)]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # epochs with one satellite
        common = np.sqrt(np.nanmean(w**2))
        diff = np.sqrt(np.nanmean((w - np.nanmean(w, axis=1, keepdims=True)) ** 2))
    dv = r1["vel_enu"] - r0["vel_enu"]
    dv_h = np.sqrt(np.nanmean(np.sum(dv[:, :2] ** 2, axis=1)))
    assert 3e-3 < common < 1e-2 and diff < 1e-3 and dv_h < 5e-3
