"""Seed 003 (satcom on the move): servo angles, CLI, dual-quaternion control, 8-state filter, servo model."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from aidnav.estimators import satcom
from aidnav.estimators.satcom import (
    Nav8Config,
    NavRun,
    ServoAxis,
    beam_errors,
    dual_quaternion_track,
    quat_angle_between,
    quat_angles_between,
    reference_chase,
    run_loose_nav,
    run_nav8,
    servo_angles,
    servo_commands,
    servo_track,
    signal_loss_db,
)
from aidnav.nav.rotations import (
    attitude_error_batch,
    euler_from_quat,
    euler_to_quat_batch,
    quat_from_euler,
    quat_from_rotvec,
    quat_mult,
    quat_normalize,
)

D = np.pi / 180.0


# ------------------------------------------------------------------------------------------- servo angles
def test_servo_angles_known_answers():
    # level, heading North, at the satellite's longitude in the northern hemisphere: due South
    r = servo_angles(39.9, 110.5, 0.0, 0.0, 0.0, 0.0, 110.5)
    assert r["azimuth_deg"] == pytest.approx(180.0, abs=1e-9)
    L = 39.9 * D
    el_textbook = np.degrees(np.arctan((np.cos(L) - 6378137.0 / 42164.17e3) / np.sin(L)))
    assert r["elevation_deg"] == pytest.approx(el_textbook, abs=0.2)
    assert r["polarization_deg"] == pytest.approx(0.0, abs=1e-9)
    # heading South: the satellite is straight ahead; heading West: on the left (az 270, clockwise)
    az = servo_angles(39.9, 110.5, 0, 0, 0, 180.0, 110.5)["azimuth_deg"]
    assert (az + 180.0) % 360.0 - 180.0 == pytest.approx(0.0, abs=1e-9)
    assert servo_angles(39.9, 110.5, 0, 0, 0, 270.0, 110.5)["azimuth_deg"] == pytest.approx(270.0, abs=1e-9)
    # satellite west of the site: azimuth west of South, positive skew (§4.3 level check)
    r = servo_angles(39.9, 116.4, 0.0, 0.0, 0.0, 0.0, 110.5)
    assert 180.0 < r["azimuth_deg"] < 200.0
    skew = -np.degrees(np.arctan(np.sin(-5.9 * D) / np.tan(L)))
    assert r["polarization_deg"] == pytest.approx(skew, abs=0.2)
    h = servo_angles(39.9, 116.4, 0.0, 0.0, 0.0, 0.0, 110.5, polarization="horizontal")
    assert (h["polarization_deg"] - r["polarization_deg"]) % 180.0 == pytest.approx(90.0)


def test_cli_satcom_point_json_matches_function():
    from aidnav.cli import app

    runner = CliRunner()
    args = ["satcom", "point", "--lat", "39.9", "--lon", "116.4", "--height", "55", "--roll", "-2.5",
            "--pitch", "1.5", "--heading", "123", "--sat-lon", "110.5"]
    res = runner.invoke(app, [*args, "--json"])
    assert res.exit_code == 0, res.output
    got = json.loads(res.output)
    assert set(got) == {"azimuth_deg", "elevation_deg", "polarization_deg"}
    want = servo_angles(39.9, 116.4, 55.0, -2.5, 1.5, 123.0, 110.5)
    for k, v in want.items():
        assert got[k] == pytest.approx(v, abs=1e-12)
    res = runner.invoke(app, [*args, "--json", "--polarization", "horizontal"])
    assert res.exit_code == 0
    hz = servo_angles(39.9, 116.4, 55.0, -2.5, 1.5, 123.0, 110.5, polarization="horizontal")
    assert json.loads(res.output)["polarization_deg"] == pytest.approx(hz["polarization_deg"])
    res = runner.invoke(app, args)
    assert res.exit_code == 0 and "azimuth" in res.output and "polarization" in res.output
    res = runner.invoke(app, [*args, "--polarization", "circular"])
    assert res.exit_code == 2


# ------------------------------------------------------------------------------- dual-quaternion control
def test_reference_chase_spec_4_5():
    """§4.5 chase with the total rate bounded (issue 27; docs/seed_003_closing_times.md).

    The common ΔΘ leaves the rotation ε between q_ant and q_nav unchanged and the chase removes w_max·dt of
    it per interrupt along ε, so every axis closes when the whole rotation does:
    t ∈ [|ε_0|/w_max − dt, |ε_0|/w_max), |ε_0| the angle of the correction. (Before issue 27 the Euler
    angles were chased separately: heading 4 s, pitch and roll ≈ 1 s, total up to √3·w_max·dt.)
    """
    ch = reference_chase()
    w, dt = 0.5, 0.01
    wmdt = w * dt
    eps0 = np.degrees(quat_angle_between(quat_from_euler(0.0, 0.0, 105 * D),
                                         quat_from_euler(0.3 * D, -0.5 * D, 107 * D)))
    assert eps0 == pytest.approx(np.sqrt(0.3**2 + 0.5**2 + 2**2), rel=1e-3)  # first order
    for axis in ("heading", "pitch", "roll"):
        assert eps0 / w - dt - 1e-9 <= ch["close_time_s"][axis] < eps0 / w, axis
    # total and per-axis bounds; identity before the correction
    assert ch["max_rot_deg"] <= wmdt * (1 + 1e-9)
    assert ch["max_rot_deg"] >= wmdt * (1 - 1e-9)  # the bound is used: the chase runs at w_max
    assert max(ch["max_step_deg"].values()) <= wmdt * (1 + 1e-9)
    assert ch["max_step_deg"]["heading"] == pytest.approx(wmdt * 2.0 / eps0, rel=1e-3)  # its share
    assert ch["identity_before_rad"] <= 1e-12
    # the angle between q_ant and q_nav falls linearly at w_max (the first step is taken at the correction)
    k0 = int(np.argmax(ch["time"] >= ch["t_correction"] - 1e-9))
    tt = ch["time"][k0:] - ch["t_correction"]
    ant = euler_to_quat_batch(np.ascontiguousarray(ch["ant_rph_deg"] * D))
    nav = euler_to_quat_batch(np.ascontiguousarray(ch["nav_rph_deg"] * D))
    gap = np.degrees(quat_angles_between(ant, nav))
    assert np.abs(gap[k0:] - np.maximum(eps0 - w * (tt + dt), 0.0)).max() < 1e-9
    # the heading difference is ε_U up to second order: nearly the line 2°·(1 − w·(t + dt)/|ε_0|)
    line = 2.0 * np.maximum(1.0 - w * (tt + dt) / eps0, 0.0)
    assert np.abs(np.abs(ch["diff_deg"][k0:, 2]) - line).max() < wmdt
    # the yaw turns the tilt between pitch and roll (21° < 31°): neither crosses zero before the end
    d = ch["diff_deg"][k0:]
    open_ = tt < ch["close_time_s"]["heading"] - 1e-9
    for c in (0, 1):
        assert np.all(np.sign(d[open_, c]) == np.sign(d[0, c]))
    # converged: the antenna quaternion equals the navigation quaternion after the chase
    assert gap[-50:].max() < 1e-9


def test_chase_when_the_rate_bound_is_feasible_closes_in_t_f():
    ch = reference_chase(w_max_deg_s=5.0, correction_rph_deg=(0.0, 0.0, 2.0), yaw_rate_deg_s=0.0)
    assert ch["close_time_s"]["heading"] == pytest.approx(1.0 - 0.01, abs=1e-9)
    ch = reference_chase(w_max_deg_s=5.0, correction_rph_deg=(0.0, 0.0, 2.0), yaw_rate_deg_s=0.0, margin=2.0)
    assert ch["close_time_s"]["heading"] == pytest.approx(0.5 - 0.01, abs=1e-9)
    with pytest.raises(ValueError):
        reference_chase(margin=0.5)


def _random_run(rng, n=3000, dt=0.01, t_f=1.0, jump_deg=1.0):
    """Random body motion, navigation quaternion corrected by random jumps every T_f."""
    q = quat_from_euler(*rng.uniform([-0.1, -0.1, 0], [0.1, 0.1, 2 * np.pi]))
    q0 = q.copy()
    dth = rng.normal(size=(n, 3)) * np.array([0.3, 0.3, 1.0]) * D  # up to ~100 deg/s
    state = np.zeros((n, 10))
    corrected = np.zeros(n, bool)
    every = int(round(t_f / dt))
    for k in range(n):
        q = quat_normalize(quat_mult(q, quat_from_rotvec(dth[k])))
        if (k + 1) % every == 0 and k < n - 8 * every:
            q = quat_normalize(quat_mult(quat_from_rotvec(rng.normal(size=3) * jump_deg * D / np.sqrt(3)), q))
            corrected[k] = True
        state[k, 6:10] = q
    return NavRun(time=(np.arange(n) + 1) * dt, state=state, dtheta=dth, dt=np.full(n, dt),
                  corrected=corrected, q0=q0, t0=0.0)


def _pre_command_gap(nav, res):
    """Angle between q_ant after the common ΔΘ (before the command) and q_nav, per interrupt."""
    q_prev = np.vstack([nav.q0[None, :], res.q_ant[:-1]])
    pre = np.array([quat_normalize(quat_mult(q_prev[k], quat_from_rotvec(nav.dtheta[k])))
                    for k in range(len(q_prev))])
    return quat_angles_between(pre, np.ascontiguousarray(nav.state[:, 6:10]))


@pytest.mark.parametrize("w_max_deg_s", [0.5, 2.0])
def test_dual_quaternion_rate_bound_and_convergence(w_max_deg_s):
    rng = np.random.default_rng(int(w_max_deg_s * 10))
    nav = _random_run(rng)
    w = w_max_deg_s * D
    res = dual_quaternion_track(nav, t_f=1.0, w_max=w)
    # the antenna's Euler angles never move by more than w_max·dt per interrupt beyond the ΔΘ motion
    assert np.abs(res.step).max() <= w * 0.01 * (1 + 1e-9)
    # the total rotation neither (issue 27; was ≤ √(3 + 2|sin θ|)·w_max·dt with per-axis chasing)
    rot = np.linalg.norm(res.cmd_rotvec, axis=1)
    assert rot.max() <= w * 0.01 * (1 + 1e-9)
    assert np.all(res.w <= w * (1 + 1e-12))
    # along the geodesic: the command removes exactly its rotation from the gap and never passes q_nav
    gap = quat_angles_between(res.q_ant, np.ascontiguousarray(nav.state[:, 6:10]))
    pre = _pre_command_gap(nav, res)
    assert np.abs(gap - (pre - rot)).max() < 1e-12
    assert np.all(rot <= pre + 1e-15)
    # never overshoots: the sign of an Euler difference is not reversed by a command
    before = res.diff + res.step
    moved = np.abs(res.step) > 0
    assert np.all(np.sign(before[moved]) * np.sign(res.diff[moved]) >= 0)
    # converges to the navigation quaternion once the corrections stop
    assert gap[-100:].max() < 1e-9
    assert gap.max() > 0.1 * D  # there was something to chase


def _one_step(q_ant0, q_nav, dth=None, dt=0.01):
    """A NavRun of one interrupt: the antenna starts at q_ant0, the navigation is corrected to q_nav."""
    dth = np.zeros(3) if dth is None else dth
    state = np.zeros((1, 10))
    state[0, 6:10] = q_nav
    return NavRun(time=np.array([dt]), state=state, dtheta=dth[None, :], dt=np.array([dt]),
                  corrected=np.array([True]), q0=q_ant0, t0=0.0)


def test_total_rotation_bound_for_random_simultaneous_three_axis_errors():
    """Issue 27: for any simultaneous (roll, pitch, heading) difference the antenna attitude's total change
    per interrupt beyond the vehicle motion is min(w·dt, |ε|) ≤ w_max·dt (+ rounding), along the geodesic."""
    rng = np.random.default_rng(27)
    dt = 0.01
    n_guard = 0
    for _ in range(300):
        rph = rng.uniform([-0.6, -0.6, 0.0], [0.6, 0.6, 2 * np.pi])  # up to ±34° of roll and pitch
        err = rng.normal(size=3) * rng.choice([0.01, 0.3, 3.0]) * D  # feasible and infeasible
        w_max = rng.uniform(0.1, 5.0) * D
        margin = rng.choice([1.0, 1.5])
        t_f = rng.choice([0.5, 1.0, 2.0])
        dth = rng.normal(size=3) * 0.5 * D  # the same increment for both
        q_nav0 = quat_from_euler(*rph)
        q_ant0 = quat_from_euler(*(rph + err))
        q_nav = quat_normalize(quat_mult(q_nav0, quat_from_rotvec(dth)))
        nav = _one_step(q_ant0, q_nav, dth, dt)
        res = dual_quaternion_track(nav, t_f=t_f, w_max=w_max, margin=margin)
        rot = np.linalg.norm(res.cmd_rotvec[0])
        eps = quat_angle_between(q_ant0, q_nav0)  # the common increment does not change it
        assert quat_angle_between(quat_normalize(quat_mult(q_ant0, quat_from_rotvec(dth))), q_nav) == \
            pytest.approx(eps, abs=1e-14)
        assert rot <= w_max * dt * (1 + 1e-9) + 1e-15
        assert np.abs(res.step[0]).max() <= w_max * dt * (1 + 1e-9)
        want = min(w_max * dt, margin * eps / t_f * dt, eps)
        if rot < want * (1 - 1e-9):
            n_guard += 1  # the per-Euler-angle guard shrank the step (off level only)
            # to the bound, from below, within the step's curvature in Euler angles (relative O(w_max·dt))
            assert np.abs(res.step[0]).max() >= w_max * dt * (1 - 10 * w_max * dt)
            assert max(abs(rph[0]), abs(rph[1])) > 0.05
        else:
            assert rot == pytest.approx(want, rel=1e-9, abs=1e-15)
        # on the geodesic: what is left is the rest of the same rotation
        left = quat_angle_between(res.q_ant[0], q_nav)
        assert left == pytest.approx(eps - rot, abs=1e-13)
    assert n_guard < 30  # the guard is the exception


@pytest.mark.parametrize("axis", [0, 1, 2])
@pytest.mark.parametrize("attitude_deg", [(0.0, 0.0, 100.0), (12.0, -8.0, 250.0)])
def test_single_axis_chase_is_the_per_axis_rule(axis, attitude_deg):
    """One Euler angle differing alone (any attitude, no vehicle rotation): |d| falls by exactly
    min(w·dt, |d|) per interrupt, w = min(w_max, |Δ|/T_f) latched, the other two stay 0 (§4.2
    behaviour 2; the rule before issue 27, unchanged for one axis)."""
    dt, t_f, w_max = 0.01, 1.0, 0.5 * D
    n = 700
    rph = np.array(attitude_deg) * D
    jump = np.zeros(3)
    jump[axis] = (2.0, -0.3, 0.8)[axis] * D  # roll, pitch, heading; two above w_max·T_f, one below
    q_pre = quat_from_euler(*rph)
    q_post = quat_from_euler(*(rph + jump))
    state = np.zeros((n, 10))
    state[0, 6:10] = q_post
    state[1:, 6:10] = q_post
    corrected = np.zeros(n, bool)
    corrected[0] = True
    nav = NavRun(time=(np.arange(n) + 1) * dt, state=state, dtheta=np.zeros((n, 3)), dt=np.full(n, dt),
                 corrected=corrected, q0=q_pre, t0=0.0)
    res = dual_quaternion_track(nav, t_f=t_f, w_max=w_max)
    big = abs(jump[axis])
    w = min(w_max, big / t_f)
    k = np.arange(n)
    want = np.maximum(big - (k + 1) * w * dt, 0.0)
    col = {0: 1, 1: 0, 2: 2}[axis]  # patent order [pitch, roll, yaw]
    assert np.abs(np.abs(res.diff[:, col]) - want).max() < 1e-12
    others = [c for c in range(3) if c != col]
    assert np.abs(res.diff[:, others]).max() < 1e-12
    assert np.abs(np.abs(res.step[:, col]) - np.minimum(w * dt, np.concatenate([[big], want[:-1]]))).max() \
        < 1e-12
    closed = np.flatnonzero(np.abs(res.diff[:, col]) < 1e-12)[0]
    assert closed == int(np.ceil(big / (w * dt) - 1e-9)) - 1


def test_single_heading_chase_while_yawing_is_unchanged():
    """§4.5 with a heading correction alone: the old per-axis result, 2°/w_max − dt = 3.99 s."""
    ch = reference_chase(correction_rph_deg=(0.0, 0.0, 2.0))
    assert ch["close_time_s"]["heading"] == pytest.approx(3.99, abs=1e-9)
    assert ch["max_rot_deg"] == pytest.approx(0.005, rel=1e-9)
    k0 = int(np.argmax(ch["time"] >= ch["t_correction"] - 1e-9))
    tt = ch["time"][k0:] - ch["t_correction"]
    assert np.abs(np.abs(ch["diff_deg"][k0:, 2]) - np.maximum(2.0 - 0.5 * (tt + 0.01), 0.0)).max() < 1e-9
    assert np.abs(ch["diff_deg"][:, :2]).max() < 1e-9


def test_dual_quaternion_identical_without_corrections():
    rng = np.random.default_rng(5)
    nav = _random_run(rng, n=5000, jump_deg=0.0)
    nav.corrected[:] = False
    # navigation quaternion propagated by the same ΔΘ, no correction
    res = dual_quaternion_track(nav, t_f=1.0, w_max=0.5 * D)
    gap = quat_angles_between(res.q_ant, np.ascontiguousarray(nav.state[:, 6:10]))
    assert gap.max() <= 1e-12
    with pytest.raises(ValueError):
        dual_quaternion_track(nav, margin=0.9)


def test_servo_commands_use_the_given_quaternion():
    """Servo commands come from the quaternion passed (the antenna-control one), not from the state's."""
    n = 3
    state = np.zeros((n, 10))
    state[:, 0], state[:, 1], state[:, 2] = 39.9 * D, 116.4 * D, 50.0
    q_nav = np.array([quat_from_euler(0.0, 0.0, 10 * D)] * n)
    state[:, 6:10] = q_nav
    q_ant = np.array([quat_from_euler(0.0, 0.0, 12 * D)] * n)
    c = servo_commands(state, q_ant, 110.5 * D)
    r = servo_angles(39.9, 116.4, 50.0, 0.0, 0.0, 12.0, 110.5)
    assert np.degrees(c[0]) == pytest.approx([r["azimuth_deg"], r["elevation_deg"], r["polarization_deg"]])


# -------------------------------------------------------------------------------------- servo model
def test_servo_model_respects_limits_and_tracks():
    rng = np.random.default_rng(2)
    n, dt = 3000, 0.01
    t = np.arange(n) * dt
    cmd = np.column_stack([
        (0.3 * np.sin(0.7 * t) + 2.0 * (t > 5) + 0.5 * t * (t > 20)) % (2 * np.pi),  # az: steps and a ramp
        0.7 + 0.05 * np.sin(2 * t) + 0.2 * (t > 10),
        ((0.2 * np.sin(0.3 * t) + 1.2 * (t > 15)) + 0.5 * np.pi) % np.pi - 0.5 * np.pi,
    ]) + rng.normal(size=(n, 3)) * 1e-4
    axes = (ServoAxis(60.0, 200.0, 4.0, 0.8), ServoAxis(40.0, 150.0, 4.0, 0.8),
            ServoAxis(30.0, 100.0, 3.0, 0.8))
    sv = servo_track(np.full(n, dt), cmd, axes)
    rate_max = np.array([60.0, 40.0, 30.0]) * D
    acc_max = np.array([200.0, 150.0, 100.0]) * D
    assert np.all(np.abs(sv.rate) <= rate_max * (1 + 1e-12))
    assert np.all(sv.accel <= acc_max * (1 + 1e-9))
    assert np.all(sv.demand.max(axis=0) > acc_max)  # the steps did ask for more
    assert np.all(sv.saturated_fraction > 0)
    # also between samples: finite differences of the output rate
    assert np.all(np.abs(np.diff(sv.rate, axis=0)) <= acc_max * dt * (1 + 1e-9))
    # tracking: settled before the az ramp, ramp (0.5 rad/s < 60 deg/s) followed closely
    e = np.column_stack([(sv.angle[:, 0] - cmd[:, 0] + np.pi) % (2 * np.pi) - np.pi,
                         sv.angle[:, 1] - cmd[:, 1],
                         (sv.angle[:, 2] - cmd[:, 2] + 0.5 * np.pi) % np.pi - 0.5 * np.pi])
    assert np.abs(e[(t > 9) & (t < 10)]).max() < 0.2 * D
    assert np.abs(e[(t > 25), 0]).max() < 0.2 * D
    assert -0.5 * np.pi <= sv.angle[:, 2].min() and sv.angle[:, 2].max() <= 0.5 * np.pi
    assert 0.0 <= sv.angle[:, 0].min() and sv.angle[:, 0].max() < 2 * np.pi
    # second-order step response: a 1 deg elevation step settles with a small overshoot
    c2 = np.zeros((400, 3))
    c2[:, 1] = 0.5
    c2[50:, 1] += 1 * D
    s2 = servo_track(np.full(400, dt), c2, axes)
    assert s2.angle[-1, 1] == pytest.approx(0.5 + D, abs=1e-6)
    assert s2.angle[:, 1].max() < 0.5 + 1.1 * D


def test_beam_errors_and_signal_loss():
    n = 5
    lat, lon, h = np.full(n, 39.9 * D), np.full(n, 116.4 * D), np.full(n, 50.0)
    rph = np.tile([2 * D, -1 * D, 40 * D], (n, 1))
    state = np.column_stack([lat, lon, h])
    cmd = servo_commands(state, euler_to_quat_batch(rph), 110.5 * D)
    e, pe = beam_errors(lat, lon, h, rph, cmd, 110.5 * D)
    assert np.abs(e).max() < 1e-9 and np.abs(pe).max() < 1e-9
    off = cmd.copy()
    off[:, 1] += 0.3 * D
    off[:, 2] += 5 * D
    e, pe = beam_errors(lat, lon, h, rph, off, 110.5 * D)
    assert np.degrees(e) == pytest.approx(np.full(n, 0.3), abs=1e-9)
    assert np.degrees(pe) == pytest.approx(np.full(n, 5.0), abs=1e-9)
    bw = 2 * D
    assert signal_loss_db(1 * D, bw) == pytest.approx(3.0)
    assert signal_loss_db(0.0, bw, pol_error=np.pi / 3) == pytest.approx(-20 * np.log10(0.5))
    assert signal_loss_db(0.0, bw) == 0.0


# --------------------------------------------------------------------------- navigation on a simulated run
@pytest.fixture(scope="module")
def sim_run():
    from aidnav.sim.run import simulate
    from aidnav.sim.scenario import Scenario

    scn = Scenario.model_validate(dict(
        name="satcom_test", seed=1,
        initial=dict(lat_deg=39.9, lon_deg=116.4, height_m=50.0, heading_deg=60.0),
        imu_rate_hz=100.0, transition_s=2.0,
        segments=[dict(type="static", duration_s=20), dict(type="accelerate", duration_s=10, to_speed_m_s=15),
                  dict(type="straight", duration_s=30), dict(type="turn", angle_deg=90, rate_deg_s=6),
                  dict(type="straight", duration_s=30), dict(type="turn", angle_deg=-60, rate_deg_s=5),
                  dict(type="straight", duration_s=40)],
        sensors=dict(imu=dict(grade="mems", gyro_bias_deg_h=3.0),
                     gnss=dict(rate_hz=1.0, sigma_pos_m=[1.5, 1.5, 3.0], sigma_vel_m_s=[0.1, 0.1, 0.2]))))
    sim = simulate(scn, seed=7)
    tr = sim.truth
    rph0 = tr.rph[0] + np.array([1.0, -0.8, 0.2]) * D  # initial alignment errors
    args = (sim.imu, sim.gnss, tr.lat[0], tr.lon[0], tr.height[0], tr.vel[0], rph0)
    return sim, args


def _level_rms(nav, truth, t_from):
    q_true = euler_to_quat_batch(np.ascontiguousarray(truth.rph[1:]))
    phi = attitude_error_batch(np.ascontiguousarray(nav.state[:, 6:10]), q_true)
    m = nav.time >= t_from
    return np.degrees(np.sqrt(np.mean(phi[m, 0] ** 2 + phi[m, 1] ** 2))), np.degrees(phi[:, 2])


def test_nav8_reduces_level_attitude_error(sim_run):
    sim, args = sim_run
    cfg = Nav8Config(gyro_bias_sigma_deg_h=6.0, init_level_sigma_deg=1.5)
    nav = run_nav8(*args, cfg=cfg)
    free = run_nav8(*args, cfg=cfg, use_filter=False)
    lev, head = _level_rms(nav, sim.truth, 60.0)
    lev_free, head_free = _level_rms(free, sim.truth, 60.0)
    assert lev < 0.3 * lev_free
    assert lev < 0.25  # accelerometer bias / misalignment limited (mems: 1 mg, 360")
    # one correction per GPS fix; heading is not corrected by the 8-state filter
    assert nav.corrected.sum() == len(sim.gnss)
    assert not free.corrected.any()
    assert nav.filter_x.shape == (len(sim.gnss), 8)
    assert np.abs(head - head_free).max() < 0.1  # same heading drift (only level attitude is corrected)
    # ΔΘ reproduces the propagation between corrections: q_k = q_{k-1} ⊗ q(ΔΘ_k)
    q = nav.state[:, 6:10]
    pred = np.array([quat_mult(q[k - 1], quat_from_rotvec(nav.dtheta[k])) for k in range(1, 400)])
    ok = ~nav.corrected[1:400]
    assert quat_angles_between(pred[ok], np.ascontiguousarray(q[1:400][ok])).max() < 1e-12
    # the antenna quaternion under this navigation: rate bound and chase
    res = dual_quaternion_track(nav, t_f=1.0, w_max=0.5 * D)
    assert np.abs(res.step).max() <= 0.5 * D * 0.01 * (1 + 1e-9)
    assert np.linalg.norm(res.cmd_rotvec, axis=1).max() <= 0.5 * D * 0.01 * (1 + 1e-9)
    gap = quat_angles_between(res.q_ant, np.ascontiguousarray(q))
    pre = np.flatnonzero(nav.corrected)[10:] - 1
    assert np.degrees(gap[pre]).max() < 0.01  # closes within each filter period once converged


def test_loose_15_state_as_the_navigation(sim_run):
    from aidnav.filters.config import LooseConfig

    sim, args = sim_run
    cfg = LooseConfig.model_validate(dict(
        imu=dict(arw_deg_sqrt_h=0.3, vrw_m_s_sqrt_h=0.1, gyro_bias_sigma_deg_h=6.0,
                 accel_bias_sigma_ug=1000.0,
                 gyro_bias_tau_s=300.0, accel_bias_tau_s=300.0),
        init=dict(attitude_sigma_deg=[1.5, 1.5, 0.6])))
    nav = run_loose_nav(*args, cfg=cfg)
    free = run_nav8(*args, use_filter=False)
    lev, _ = _level_rms(nav, sim.truth, 60.0)
    lev_free, _ = _level_rms(free, sim.truth, 60.0)
    assert lev < 0.3 * lev_free
    assert nav.corrected.sum() >= len(sim.gnss)
    q = nav.state[:, 6:10]
    idx = np.flatnonzero(~nav.corrected[1:2000]) + 1
    pred = np.array([quat_mult(q[k - 1], quat_from_rotvec(nav.dtheta[k])) for k in idx])
    assert quat_angles_between(pred, np.ascontiguousarray(q[idx])).max() < 1e-12
    res = dual_quaternion_track(nav, t_f=1.0, w_max=0.5 * D)
    assert np.abs(res.step).max() <= 0.5 * D * 0.01 * (1 + 1e-9)


def test_quat_angle_between():
    q = quat_from_euler(0.1, 0.2, 0.3)
    p = quat_normalize(quat_mult(quat_from_rotvec(np.array([0.0, 0.0, 1e-7])), q))
    assert quat_angle_between(q, p) == pytest.approx(1e-7, rel=1e-6)
    assert quat_angle_between(q, -q) < 1e-15
    assert np.degrees(euler_from_quat(q)[0]) == pytest.approx(np.degrees(0.1))
    assert satcom.servo_angles is servo_angles


def test_reproduction_short(tmp_path):
    from aidnav.experiments.reproduce.seed_003 import run

    s = run(tmp_path, runs=1, base_seed=3, route="short")
    doc = json.loads((tmp_path / "summary.json").read_text())
    assert doc == s
    assert doc["seed"] == "003" and doc["runs"] == 1 and doc["base_seed"] == 3
    for f in doc["figures"]:
        assert (tmp_path / f).stat().st_size > 1000
    rows = [r for t in doc["tables"] for r in t["rows"]]
    from aidnav.experiments.reproduce.summary import _ROW_KEYS

    assert all(set(r) == set(_ROW_KEYS) for r in rows)
    assert all(r["paper"] is None for r in rows)
    assert all((r["holds"] is None) == (r["target"] is None) for r in rows)
    # every SPEC row holds; the sensitivity rows (the per-axis chase) may fail by design and say why
    failing = [r["quantity"] for r in rows if r["spec"] and r["holds"] is False]
    assert not failing, failing
    assert all(r["holds"] == (r["verdict"] == "holds") for r in rows if r["target"] is not None)
