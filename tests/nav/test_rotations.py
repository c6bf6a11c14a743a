"""Property tests of ``aidnav.nav.rotations`` against ``scipy.spatial.transform.Rotation``.

Conventions under test (``docs/conventions.md``): C = C_b^n (body RFU → nav ENU),
C_b^n = R3(-heading) · R1(pitch) · R2(roll) with active elementary rotations, which is scipy's
*intrinsic* ``Rotation.from_euler('ZXY', [-heading, pitch, roll])``; Hamilton quaternions, scalar
first (scipy's are scalar last); attitude error φ with C_est = (I - [φ×]) C_true.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation as R

from aidnav.nav import rotations as ro

PI = np.pi
PROPS = settings(max_examples=200, deadline=None)

# ---------------------------------------------------------------------------- strategies
rolls = st.floats(-PI, PI, exclude_min=True, allow_nan=False)
pitches = st.floats(-PI / 2, PI / 2, allow_nan=False)
headings = st.floats(0.0, 2 * PI, exclude_max=True, allow_nan=False)
pitches_regular = st.floats(-PI / 2 + 1e-3, PI / 2 - 1e-3)
unit = st.floats(-1.0, 1.0, allow_nan=False)


@st.composite
def axes(draw):
    v = np.array([draw(unit), draw(unit), draw(unit)])
    n = np.linalg.norm(v)
    if n < 1e-3:
        v, n = np.array([0.0, 0.0, 1.0]), 1.0
    return v / n


@st.composite
def quats(draw):
    """Unit quaternions (scalar first) of either sign."""
    q = np.array([draw(unit), draw(unit), draw(unit), draw(unit)])
    n = np.linalg.norm(q)
    if n < 1e-3:
        q, n = np.array([1.0, 0.0, 0.0, 0.0]), 1.0
    return q / n


# rotation angles: general, tiny (< 1e-8 rad) and close to π (π - 1e-9 ... π - 1e-3)
angles_general = st.floats(0.0, PI - 1e-3)
angles_tiny = st.floats(-14.0, -8.0).map(lambda e: 10.0**e)
angles_near_pi = st.floats(-9.0, -3.0).map(lambda e: PI - 10.0**e)
angles_all = st.one_of(angles_general, angles_tiny, angles_near_pi)


@st.composite
def rotvecs(draw, angles=angles_all):
    return draw(angles) * draw(axes())


# ---------------------------------------------------------------------------- helpers
def sp_euler(roll, pitch, heading):
    """scipy rotation of our (roll, pitch, heading): intrinsic Z(-heading), X(pitch), Y(roll)."""
    return R.from_euler("ZXY", [-heading, pitch, roll])


def to_sp(q):
    """Our scalar-first quaternion → scipy Rotation (scalar last)."""
    return R.from_quat([q[1], q[2], q[3], q[0]])


def from_sp(rot):
    """scipy Rotation → scalar-first quaternion."""
    x, y, z, w = rot.as_quat()
    return np.array([w, x, y, z])


def assert_quat_close(q, p, atol=1e-12):
    """Equal as rotations: q = ±p."""
    assert min(np.max(np.abs(q - p)), np.max(np.abs(q + p))) <= atol, (q, p)


def wrap(a):
    return (a + PI) % (2 * PI) - PI


# ---------------------------------------------------------------------------- conventions
def test_heading_90_sends_forward_to_east():
    c = ro.dcm_from_euler(0.0, 0.0, PI / 2)
    assert np.allclose(c @ [0.0, 1.0, 0.0], [1.0, 0.0, 0.0], atol=1e-15)
    assert np.allclose(
        ro.quat_rotate(ro.quat_from_euler(0.0, 0.0, PI / 2), np.array([0.0, 1.0, 0.0])),
        [1.0, 0.0, 0.0],
        atol=1e-15,
    )
    # heading is clockwise from North: 45° → forward to North-East
    c = ro.dcm_from_euler(0.0, 0.0, PI / 4)
    assert np.allclose(c @ [0.0, 1.0, 0.0], [np.sqrt(0.5), np.sqrt(0.5), 0.0], atol=1e-15)


def test_pitch_and_roll_signs():
    # pitch positive nose up: forward axis gets a positive Up component
    assert (ro.dcm_from_euler(0.0, 0.1, 0.0) @ [0.0, 1.0, 0.0])[2] == pytest.approx(np.sin(0.1))
    # roll positive right wing down: right axis gets a negative Up component
    assert (ro.dcm_from_euler(0.1, 0.0, 0.0) @ [1.0, 0.0, 0.0])[2] == pytest.approx(-np.sin(0.1))
    # identity
    assert np.allclose(ro.dcm_from_euler(0.0, 0.0, 0.0), np.eye(3))
    assert np.allclose(ro.quat_from_euler(0.0, 0.0, 0.0), [1.0, 0.0, 0.0, 0.0])


@PROPS
@given(rolls, pitches, headings)
def test_dcm_from_euler_is_scipy_ZXY(roll, pitch, heading):
    c = ro.dcm_from_euler(roll, pitch, heading)
    assert np.allclose(c, sp_euler(roll, pitch, heading).as_matrix(), rtol=0, atol=1e-14)
    # elementary-rotation product R3(-heading) R1(pitch) R2(roll)
    r3 = R.from_rotvec([0.0, 0.0, -heading]).as_matrix()
    r1 = R.from_rotvec([pitch, 0.0, 0.0]).as_matrix()
    r2 = R.from_rotvec([0.0, roll, 0.0]).as_matrix()
    assert np.allclose(c, r3 @ r1 @ r2, rtol=0, atol=1e-14)
    assert np.allclose(c @ c.T, np.eye(3), atol=1e-14)


@PROPS
@given(rolls, pitches, headings)
def test_quat_from_euler_matches_scipy(roll, pitch, heading):
    q = ro.quat_from_euler(roll, pitch, heading)
    assert q[0] >= 0.0
    assert np.linalg.norm(q) == pytest.approx(1.0, abs=1e-15)
    assert_quat_close(q, from_sp(sp_euler(roll, pitch, heading)), atol=1e-14)


# ---------------------------------------------------------------------------- Euler <-> DCM
def _check_euler_ranges(r, p, h):
    assert -PI < r <= PI
    assert -PI / 2 <= p <= PI / 2
    assert 0.0 <= h < 2 * PI


@PROPS
@given(rolls, pitches_regular, headings)
def test_euler_roundtrip(roll, pitch, heading):
    r, p, h = ro.euler_from_dcm(ro.dcm_from_euler(roll, pitch, heading))
    _check_euler_ranges(r, p, h)
    assert abs(p - pitch) < 1e-12
    assert abs(wrap(r - roll)) < 1e-10
    assert abs(wrap(h - heading)) < 1e-10
    # from scipy's matrix as well
    r2, p2, h2 = ro.euler_from_dcm(sp_euler(roll, pitch, heading).as_matrix())
    assert abs(p2 - pitch) < 1e-12 and abs(wrap(r2 - roll)) < 1e-10 and abs(wrap(h2 - heading)) < 1e-10
    # and through the quaternion
    r3, p3, h3 = ro.euler_from_quat(ro.quat_from_euler(roll, pitch, heading))
    _check_euler_ranges(r3, p3, h3)
    assert abs(p3 - pitch) < 1e-12 and abs(wrap(r3 - roll)) < 1e-10 and abs(wrap(h3 - heading)) < 1e-10


@PROPS
@given(rolls, st.floats(-7.0, -3.0), st.sampled_from([-1.0, 1.0]), headings)
def test_euler_gimbal_lock_neighbourhood(roll, log_delta, sign, heading):
    """pitch = ±(90° - δ), δ = 1e-7 ... 1e-3 rad: only the combined rotation must be reproduced."""
    pitch = sign * (PI / 2 - 10.0**log_delta)
    c = ro.dcm_from_euler(roll, pitch, heading)
    r, p, h = ro.euler_from_dcm(c)
    _check_euler_ranges(r, p, h)
    assert np.allclose(ro.dcm_from_euler(r, p, h), c, rtol=0, atol=1e-8)
    assert abs(p - pitch) < 1e-8


@pytest.mark.parametrize("pitch", [PI / 2, -PI / 2])
@pytest.mark.parametrize("roll,heading", [(0.0, 0.0), (0.3, 1.0), (-2.0, 5.0), (PI, 6.2)])
def test_euler_at_gimbal_lock(pitch, roll, heading):
    c = ro.dcm_from_euler(roll, pitch, heading)
    r, p, h = ro.euler_from_dcm(c)
    _check_euler_ranges(r, p, h)
    assert r == 0.0 and p == pitch
    assert np.allclose(ro.dcm_from_euler(r, p, h), c, atol=1e-14)


@PROPS
@given(rolls, pitches_regular, st.one_of(st.floats(-1e-6, 1e-6), st.floats(2 * PI - 1e-6, 2 * PI + 1e-6)))
def test_heading_wraparound(roll, pitch, heading):
    """Headings near 0/360° (inputs slightly negative or ≥ 2π too) come back in [0, 2π)."""
    r, p, h = ro.euler_from_dcm(ro.dcm_from_euler(roll, pitch, heading))
    _check_euler_ranges(r, p, h)
    assert abs(wrap(h - heading)) < 1e-12
    assert min(h, 2 * PI - h) < 2e-6


def test_heading_wraparound_exact_edges():
    for heading in (-1e-300, -1e-17, 0.0, 1e-17, 2 * PI - 1e-15, 2 * PI, np.nextafter(2 * PI, 0.0)):
        r, p, h = ro.euler_from_dcm(ro.dcm_from_euler(0.1, 0.2, heading))
        _check_euler_ranges(r, p, h)
        assert min(h, 2 * PI - h) < 1e-14
    # roll of exactly ±180° comes back as +180°
    r, p, h = ro.euler_from_dcm(ro.dcm_from_euler(PI, 0.2, 1.0))
    assert r == pytest.approx(PI) and r > 0


# ---------------------------------------------------------------------------- DCM <-> quaternion
@PROPS
@given(quats())
def test_dcm_from_quat_matches_scipy(q):
    c = ro.dcm_from_quat(q)
    assert np.allclose(c, to_sp(q).as_matrix(), rtol=0, atol=1e-14)
    assert np.allclose(ro.dcm_from_quat(-q), c, atol=0)  # q and -q are the same rotation


@PROPS
@given(quats())
def test_quat_from_dcm_matches_scipy(q):
    c = to_sp(q).as_matrix()
    p = ro.quat_from_dcm(c)
    assert p[0] >= 0.0
    assert np.linalg.norm(p) == pytest.approx(1.0, abs=1e-15)
    assert_quat_close(p, q, atol=1e-14)
    assert_quat_close(p, from_sp(R.from_matrix(c)), atol=1e-14)


@pytest.mark.parametrize("k", range(4))
def test_quat_from_dcm_all_shepperd_branches(k):
    """Each quaternion component dominant (incl. 180° rotations about x, y, z)."""
    rng = np.random.default_rng(k)
    for _ in range(200):
        q = rng.normal(size=4) * 0.1
        q[k] = 1.0
        q /= np.linalg.norm(q)
        assert_quat_close(ro.quat_from_dcm(ro.dcm_from_quat(q)), q, atol=1e-14)
    q = np.zeros(4)
    q[k] = 1.0
    assert_quat_close(ro.quat_from_dcm(ro.dcm_from_quat(q)), q, atol=0)


@PROPS
@given(quats())
def test_quat_conj_and_normalize(q):
    ident = ro.quat_mult(q, ro.quat_conj(q))
    assert np.allclose(ident, [1.0, 0.0, 0.0, 0.0], atol=1e-15)
    assert_quat_close(ro.quat_conj(q), from_sp(to_sp(q).inv()), atol=1e-15)
    n = ro.quat_normalize(3.7 * q)
    assert n[0] >= 0 and np.linalg.norm(n) == pytest.approx(1.0, abs=1e-15)
    assert_quat_close(n, q, atol=1e-15)


# ---------------------------------------------------------------------------- rotation vectors
@PROPS
@given(rotvecs())
def test_quat_from_rotvec_matches_scipy(rv):
    q = ro.quat_from_rotvec(rv)
    ref = from_sp(R.from_rotvec(rv))
    assert np.linalg.norm(q) == pytest.approx(1.0, abs=1e-15)
    assert np.allclose(q, ref * np.sign(ref[0]), rtol=0, atol=1e-15)  # same sign: angle < π
    # tiny angles: the vector part is exactly linear in rv (no loss of relative precision)
    a = np.linalg.norm(rv)
    if a < 1e-8:
        assert np.allclose(q[1:], 0.5 * rv, rtol=1e-15, atol=0)


@PROPS
@given(rotvecs())
def test_rotvec_from_quat_matches_scipy(rv):
    q = from_sp(R.from_rotvec(rv))
    for qq in (q, -q):  # either sign of the quaternion
        r = ro.rotvec_from_quat(qq)
        a = np.linalg.norm(rv)
        assert np.linalg.norm(r) <= PI + 1e-15
        # relative precision at tiny angles, absolute elsewhere (incl. near π)
        assert np.allclose(r, rv, rtol=1e-12, atol=1e-14 if a < 1e-3 else 1e-12)
        assert np.allclose(r, R.from_quat([qq[1], qq[2], qq[3], qq[0]]).as_rotvec(), rtol=1e-12, atol=1e-12)


@PROPS
@given(rotvecs())
def test_rotvec_quat_roundtrip(rv):
    r = ro.rotvec_from_quat(ro.quat_from_rotvec(rv))
    assert np.allclose(r, rv, rtol=1e-13, atol=1e-14)


@PROPS
@given(rotvecs())
def test_dcm_from_rotvec_matches_scipy(rv):
    c = ro.dcm_from_rotvec(rv)
    assert np.allclose(c, R.from_rotvec(rv).as_matrix(), rtol=0, atol=1e-14)
    assert np.allclose(c, ro.dcm_from_quat(ro.quat_from_rotvec(rv)), rtol=0, atol=1e-14)
    a = np.linalg.norm(rv)
    if a < 1e-8:  # tiny angle: C - I = [rv×] + O(a²), without loss of relative precision
        assert np.allclose(c - np.eye(3), ro.skew(rv), rtol=1e-14, atol=a * a)


@PROPS
@given(rotvecs())
def test_rotvec_from_dcm_matches_scipy(rv):
    c = R.from_rotvec(rv).as_matrix()
    r = ro.rotvec_from_dcm(c)
    a = np.linalg.norm(rv)
    # a DCM holds the angle to ~1e-16 absolute; near π the axis sign is set by sin(angle)
    assert np.allclose(r, rv, rtol=1e-9, atol=1e-15 if a < 1e-8 else 1e-9)
    assert np.allclose(r, R.from_matrix(c).as_rotvec(), rtol=1e-9, atol=1e-9)
    assert np.allclose(ro.dcm_from_rotvec(r), c, atol=1e-14)


# ---------------------------------------------------------------------------- composition
@PROPS
@given(quats(), quats())
def test_quat_mult_is_composition(p, q):
    pq = ro.quat_mult(p, q)
    assert np.allclose(ro.dcm_from_quat(pq), ro.dcm_from_quat(p) @ ro.dcm_from_quat(q), atol=1e-14)
    assert_quat_close(pq, from_sp(to_sp(p) * to_sp(q)), atol=1e-14)
    # Hamilton product, v^n = q ⊗ v ⊗ q*
    v = np.array([0.3, -1.2, 2.0])
    vq = ro.quat_mult(ro.quat_mult(q, np.r_[0.0, v]), ro.quat_conj(q))
    assert abs(vq[0]) < 1e-14
    assert np.allclose(vq[1:], to_sp(q).apply(v), atol=1e-14)
    assert np.allclose(ro.quat_rotate(q, v), to_sp(q).apply(v), atol=1e-14)


@PROPS
@given(quats(), rotvecs())
def test_quat_update_right_multiplies(q, rv):
    """quat_update(q, rv) = q ⊗ q(rv): body-frame increment applied on the right."""
    u = ro.quat_update(q, rv)
    assert u[0] >= 0 and np.linalg.norm(u) == pytest.approx(1.0, abs=1e-15)
    assert_quat_close(u, from_sp(to_sp(q) * R.from_rotvec(rv)), atol=1e-14)
    assert np.allclose(ro.dcm_from_quat(u), ro.dcm_from_quat(q) @ ro.dcm_from_rotvec(rv), atol=1e-14)


# ---------------------------------------------------------------------------- attitude error
@PROPS
@given(
    st.lists(quats(), min_size=1, max_size=5),
    st.lists(rotvecs(st.floats(0.0, 1.0)), min_size=5, max_size=5),
)
def test_attitude_error_sign_convention(qs, phis):
    """C_est = exp(-[φ×]) C_true  ⇒  attitude_error_batch(q_est, q_true) = φ (exact rotation vector)."""
    n = len(qs)
    q_true = np.array(qs)
    phi = np.array(phis[:n])
    q_est = np.array([from_sp(R.from_rotvec(-phi[i]) * to_sp(q_true[i])) for i in range(n)])
    err = ro.attitude_error_batch(q_est, q_true)
    assert err.shape == (n, 3)
    assert np.allclose(err, phi, rtol=1e-12, atol=1e-14)
    # either quaternion sign
    assert np.allclose(ro.attitude_error_batch(-q_est, q_true), phi, rtol=1e-12, atol=1e-14)


def test_attitude_error_small_angle_first_order():
    """Small φ: C_est = (I - [φ×]) C_true to first order (the convention's definition)."""
    rng = np.random.default_rng(1)
    for _ in range(50):
        q_true = ro.quat_normalize(rng.normal(size=4))
        phi = rng.normal(size=3) * 1e-6
        c_est = (np.eye(3) - ro.skew(phi)) @ ro.dcm_from_quat(q_true)
        u, _, vt = np.linalg.svd(c_est)  # nearest rotation (removes the O(φ²) non-orthogonality)
        q_est = ro.quat_from_dcm(u @ vt)
        err = ro.attitude_error_batch(q_est[None], q_true[None])[0]
        assert np.allclose(err, phi, rtol=0, atol=1e-11)
        # the correction C ← (I + [φ̂×]) C restores the truth to second order
        c_corr = (np.eye(3) + ro.skew(err)) @ c_est
        assert np.max(np.abs(c_corr - ro.dcm_from_quat(q_true))) < 1e-11
    # a concrete sign: computed attitude rotated +1 mrad about Up (counter-clockwise, heading
    # decreased) relative to the truth means φ_U = -1 mrad
    q_true = ro.quat_from_euler(0.0, 0.0, 1.0)
    q_est = ro.quat_from_euler(0.0, 0.0, 1.0 - 1e-3)
    err = ro.attitude_error_batch(q_est[None], q_true[None])[0]
    assert np.allclose(err, [0.0, 0.0, -1e-3], atol=1e-15)


# ---------------------------------------------------------------------------- small helpers
vectors = st.lists(st.floats(-1e3, 1e3), min_size=3, max_size=3).map(np.array)


@PROPS
@given(vectors, vectors)
def test_skew_and_cross(a, b):
    s = ro.skew(a)
    assert np.array_equal(s, -s.T)
    scale = 1e-13 * (1.0 + np.abs(a).max() * np.abs(b).max())
    assert np.allclose(s @ b, np.cross(a, b), rtol=0, atol=scale)
    assert np.allclose(ro.cross(a, b), np.cross(a, b), rtol=0, atol=scale)
    assert np.allclose(ro.small_angle_dcm(a), np.eye(3) + s, atol=0)


@PROPS
@given(st.lists(st.tuples(rolls, pitches_regular, headings), min_size=1, max_size=20))
def test_euler_quat_batches(rph):
    rph = np.array(rph)
    q = ro.euler_to_quat_batch(rph)
    assert q.shape == (len(rph), 4)
    ref = np.array([from_sp(sp_euler(r, p, h)) for r, p, h in rph])
    assert np.allclose(np.abs(np.sum(q * ref, axis=1)), 1.0, atol=1e-14)
    back = ro.quat_to_euler_batch(q)
    assert np.allclose(back[:, 1], rph[:, 1], atol=1e-12)
    assert np.allclose(wrap(back[:, [0, 2]] - rph[:, [0, 2]]), 0.0, atol=1e-10)


def test_wrap_helpers():
    a = np.array([-3 * PI, -PI, -0.5, 0.0, PI - 1e-12, PI, 7.0])
    w = ro.wrap_pi(a)
    assert np.all((w >= -PI) & (w < PI))
    assert np.allclose(np.exp(1j * w), np.exp(1j * a))
    d = ro.wrap_180(np.array([-540.0, -180.0, 179.0, 180.0, 359.0, 720.5]))
    assert np.allclose(d, [-180.0, -180.0, 179.0, -180.0, -1.0, 0.5])
