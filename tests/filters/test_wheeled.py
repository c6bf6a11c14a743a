"""Issue 35, items 5–6: the no-option run's wheeled-vehicle test (:mod:`aidnav.filters.wheeled`) on
trajectories whose body-frame velocity is known by construction, and the NIS window's covariance scaling
(:func:`aidnav.filters.reinit.scale_nav`) against its closed form."""

from __future__ import annotations

import numpy as np
import pytest

from aidnav.filters.reinit import scale_nav
from aidnav.filters.wheeled import MAX_SPEED_M_S, wheeled_vehicle

RATE = 4.0  # Hz, fixes used


def _path(crab_deg=None, speed=8.0, mount_deg=(-6.0, 2.0, 95.0), seconds=240.0, att_noise_deg=0.3, seed=1,
          sway_deg=None):
    """A vehicle driving circles and straights at ``speed``; IMU mounted at ``mount_deg`` (roll, pitch,
    heading of the body against the vehicle), velocity along the vehicle's forward axis turned by
    ``crab_deg(t, course)`` (a drift/crab angle: 0 for a wheeled vehicle); attitude errors of
    ``att_noise_deg`` (1σ, white) in the solution the test sees; ``sway_deg`` a hand-held device's yaw."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, seconds, 1.0 / RATE)
    rate = np.where((t % 60.0) < 20.0, np.radians(9.0), 0.0)  # 180 deg per 20-s turn, then 40 s straight
    course = np.cumsum(rate) / RATE
    crab = np.zeros_like(t) if crab_deg is None else np.radians(crab_deg(t, course))
    heading_v = course - crab  # vehicle axis; the velocity points along the course
    if sway_deg is not None:
        heading_v = heading_v + np.radians(sway_deg) * np.sin(2 * np.pi * t / 7.0)
    vel = np.stack([speed * np.sin(course), speed * np.cos(course), np.zeros_like(t)], axis=1)
    r, p, h = np.radians(mount_deg)
    # body attitude: the vehicle's heading plus the mounting (roll/pitch of the mounting on a level road)
    rph = np.stack([np.full_like(t, r), np.full_like(t, p), heading_v + h], axis=1)
    rph = rph + np.radians(att_noise_deg) * rng.standard_normal(rph.shape)
    std_att = np.full_like(rph, np.radians(0.5))
    return t, vel, rph, std_att, t.copy()


def test_a_wheeled_vehicle_is_recognised_whatever_the_mounting():
    d = wheeled_vehicle(*_path())
    assert d["wheeled"], d["reason"]
    assert d["median_deg"] < 1.0
    # the axis found is the vehicle's forward axis in the body frame: body heading = vehicle + 95 deg,
    # so forward is the body direction 95 deg to the left of body y (RFU)
    ax = d["axis"] * np.sign(d["axis"][1] if abs(d["axis"][1]) > 0.5 else d["axis"][0])
    assert abs(abs(ax[0]) - np.sin(np.radians(95.0))) < 0.02


@pytest.mark.parametrize("label, kw", [
    ("ship, 1-kn current at 10 kn (6 deg drift turning with the course)",
     {"crab_deg": lambda t, c: 6.0 * np.cos(c)}),
    ("aircraft, 11-deg crab in a crosswind", {"crab_deg": lambda t, c: 11.0 * np.cos(c), "speed": 50.0}),
    ("hand-held device swaying 20 deg against the path", {"sway_deg": 20.0, "speed": 4.0}),
])
def test_vehicles_that_slide_are_not_called_wheeled(label, kw):
    d = wheeled_vehicle(*_path(**kw))
    assert not d["wheeled"], (label, d["reason"])


def test_a_vehicle_faster_than_any_car_is_not_called_wheeled():
    d = wheeled_vehicle(*_path(speed=MAX_SPEED_M_S + 10.0))
    assert not d["wheeled"] and "road vehicle" in d["reason"]


def test_a_straight_line_cannot_tell():
    """Without turns a constant crab angle looks like a mounting: the test does not decide."""
    t, vel, rph, sa, ta = _path()
    vel[:] = [0.0, 8.0, 0.0]
    rph[:, 2] = np.radians(95.0)
    d = wheeled_vehicle(t, vel, rph, sa, ta)
    assert not d["wheeled"] and "too little motion" in d["reason"]


def test_unknown_attitude_is_not_used():
    t, vel, rph, sa, ta = _path()
    sa[:] = np.radians(5.0)
    d = wheeled_vehicle(t, vel, rph, sa, ta)
    assert not d["wheeled"] and "known attitude" in d["reason"]


def test_window_scaling_closed_form():
    """scale_nav: P + G P G, G = (D² − I)^½ with D = √λ on δv, δp, attitude grown at most to 90°, each
    calibration state at most back to its prior (the variances of D P D; issue 35 session 12: a scaled
    copy of P added, so no combination's variance falls); positive definite; λ < 1 does nothing."""
    rng = np.random.default_rng(3)
    A = rng.standard_normal((17, 17))
    P = A @ A.T * 1e-4 + np.eye(17) * 1e-6
    P[2, 2] = 2.0  # a heading variance already near (π/2)²
    cal = np.array([[15.0, 4.0 * P[15, 15]], [16.0, 1.5 * P[16, 16]]])  # prior 4× and 1.5× the variance
    lam = 3.0
    Q = P.copy()
    scale_nav(Q, lam, cal)
    d = np.ones(17)
    d[3:9] = np.sqrt(lam)
    for i in range(3):
        d[i] = np.sqrt(min(lam, max(1.0, (np.pi / 2) ** 2 / P[i, i])))
    d[9:15] = 1.0  # the sensor-error states are not part of the navigation block
    d[15], d[16] = np.sqrt(3.0), np.sqrt(1.5)
    g = np.sqrt(d * d - 1.0)
    np.testing.assert_allclose(Q, P + P * np.outer(g, g), rtol=1e-12)
    np.testing.assert_allclose(np.diag(Q), np.diag(P) * d * d, rtol=1e-12)
    assert np.all(np.linalg.eigvalsh(Q) > 0) and np.linalg.eigvalsh(Q - P).min() > -1e-15
    Q1 = P.copy()
    scale_nav(Q1, 0.5, cal)
    np.testing.assert_array_equal(Q1, P)


def test_no_option_on_the_walk_keeps_the_nhc_off(data_dir):
    """The real walk (a person with a phone-grade IMU, walking ≤ 2 m/s): no option must not call it
    wheeled; the summary says why."""
    from aidnav.apps.process import process, read_gnss_any, read_imu_any

    d = data_dir / "rtklibexplorer_walk_0827"
    if not d.is_dir():
        pytest.skip("rtklibexplorer_walk_0827 not found")
    run = process(read_imu_any(d / "imu_1730.csv"), read_gnss_any(d / "gnss_1730_sf.pos", -21.4))
    ev = [e for e in run.summary["events"] if e.startswith("vehicle from the log")]
    assert len(ev) == 1 and "NHC off" in ev[0], run.summary["events"]
