"""Dipole-triad signal model and the seed-002 frames (§3.1–3.2, §0)."""

from __future__ import annotations

import numpy as np
import pytest

from aidnav.nav.earth import radii
from aidnav.nav.rotations import dcm_from_euler
from aidnav.nav.wave_frame import (
    P_SEED,
    base_wave_dcm,
    enu_rotation_between,
    ours_to_seed_dcm,
    seed_to_ours_dcm,
    steering_derivatives,
    steering_vector,
    wave_dcm,
    wave_params_from_dcm,
    wave_params_from_dcm_full,
    wave_rotation_jacobian,
    wave_vectors,
)
from aidnav.sim.dipole_triad import base_geometry, sample_covariance, simulate_snapshots

D = np.pi / 180.0


def _random_params(rng, n):
    return [(rng.uniform(-np.pi, np.pi), rng.uniform(-1.5, 1.5), rng.uniform(-np.pi / 2, np.pi / 2),
             rng.uniform(-np.pi / 4, np.pi / 4)) for _ in range(n)]


def test_steering_vector_matches_seed_component_form():
    rng = np.random.default_rng(0)
    for phi, th, g, eta in _random_params(rng, 50):
        a = (np.sin(g) * np.cos(eta) - 1j * np.cos(g) * np.sin(eta))
        b = (np.cos(g) * np.cos(eta) + 1j * np.sin(g) * np.sin(eta))
        seed = np.array([a * np.cos(phi) * np.sin(th) - b * np.sin(phi),
                         a * np.sin(phi) * np.sin(th) + b * np.cos(phi),
                         -a * np.cos(th)])
        A = steering_vector(phi, th, g, eta)
        np.testing.assert_allclose(A, seed, atol=1e-15)
        assert np.linalg.norm(A) == pytest.approx(1.0, abs=1e-15)
        # V Q w
        V = np.column_stack([[-np.sin(phi), np.cos(phi), 0.0],
                             [-np.cos(phi) * np.sin(th), -np.sin(phi) * np.sin(th), np.cos(th)]])
        Q = np.array([[np.cos(g), np.sin(g)], [-np.sin(g), np.cos(g)]])
        w = np.array([np.cos(eta), 1j * np.sin(eta)])
        np.testing.assert_allclose(A, V @ Q @ w, atol=1e-15)


def test_wave_frame_is_right_handed_and_matches_eq8():
    rng = np.random.default_rng(1)
    for phi, th, g, _ in _random_params(rng, 50):
        u, t1, t2 = wave_vectors(phi, th, g)
        np.testing.assert_allclose(np.cross(t1, t2), u, atol=1e-15)
        np.testing.assert_allclose(np.cross(u, t1), t2, atol=1e-15)
        C = wave_dcm(phi, th, g)
        np.testing.assert_allclose(C, np.vstack([u, t1, t2]), atol=1e-15)
        assert np.linalg.det(C) == pytest.approx(1.0)
        np.testing.assert_allclose(wave_params_from_dcm_full(C), (phi, th, g), atol=1e-12)
        _, v1, v2 = wave_vectors(phi, th, 0.0)
        np.testing.assert_allclose(v1, np.cross([0, 0, 1.0], u) / np.linalg.norm(np.cross([0, 0, 1.0], u)),
                                   atol=1e-12)


def test_steering_ambiguity_and_tilt_period():
    """(φ, θ, γ, η) and (φ ± π, −θ, −γ, −η) give A1 = −A2 (seed §2); γ + π gives −A."""
    rng = np.random.default_rng(2)
    for phi, th, g, eta in _random_params(rng, 20):
        np.testing.assert_allclose(steering_vector(phi, th, g, eta),
                                   -steering_vector(phi + np.pi, -th, -g, -eta), atol=1e-15)
        np.testing.assert_allclose(steering_vector(phi, th, g, eta),
                                   -steering_vector(phi, th, g + np.pi, eta), atol=1e-15)
        p = wave_params_from_dcm(wave_dcm(phi, th, g + np.pi))
        np.testing.assert_allclose(p, (phi, th, g), atol=1e-12)


def test_derivatives_against_finite_differences():
    rng = np.random.default_rng(3)
    h = 1e-6
    for phi, th, g, eta in _random_params(rng, 10):
        Dm = steering_derivatives(phi, th, g, eta)
        p = np.array([phi, th, g])
        J = wave_rotation_jacobian(phi, th, g)
        C = wave_dcm(phi, th, g)
        for k in range(3):
            dp = np.zeros(3)
            dp[k] = h
            num = (steering_vector(*(p + dp), eta) - steering_vector(*(p - dp), eta)) / (2 * h)
            np.testing.assert_allclose(Dm[:, k], num, atol=1e-9)
            # δ of a small parameter step: C(p + dp) ≈ (I − [δ×]) C(p)
            M = wave_dcm(*(p + dp)) @ C.T
            delta = 0.5 * np.array([M[1, 2] - M[2, 1], M[2, 0] - M[0, 2], M[0, 1] - M[1, 0]]) / h
            np.testing.assert_allclose(J[:, k], delta, atol=1e-6)


def test_frame_conversion_P():
    P = P_SEED
    np.testing.assert_allclose(P @ P.T, np.eye(3), atol=0)
    assert np.linalg.det(P) == pytest.approx(1.0)
    # NWU -> ENU: North stays North, West becomes -East, Up stays Up
    np.testing.assert_allclose(P @ [1, 0, 0], [0, 1, 0])
    np.testing.assert_allclose(P @ [0, 1, 0], [-1, 0, 0])
    np.testing.assert_allclose(P @ [0, 0, 1], [0, 0, 1])
    # FLU -> RFU: forward -> forward (y), left -> -right
    np.testing.assert_allclose(P @ [1, 0, 0], [0, 1, 0])
    np.testing.assert_allclose(P @ [0, 1, 0], [-1, 0, 0])
    # a seed attitude with the nose toward West (C_I^B = active rotation of +90° about Up)
    C_IB = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    np.testing.assert_allclose(seed_to_ours_dcm(C_IB), dcm_from_euler(0.0, 0.0, 270 * D), atol=1e-15)
    # right wing down in ours = seed's left wing up: round trip and the body axes
    C = dcm_from_euler(20 * D, -10 * D, 33 * D)
    np.testing.assert_allclose(seed_to_ours_dcm(ours_to_seed_dcm(C)), C, atol=1e-15)
    C_IB = ours_to_seed_dcm(C)
    # the nose (FLU x) in NWU, converted to ENU, equals C times RFU forward
    np.testing.assert_allclose(P @ (C_IB @ [1, 0, 0]), C @ [0, 1, 0], atol=1e-15)


def test_base_wave_dcm_corrected_eq9():
    """u in B is the aircraft → base direction: azimuth φ′ + π and elevation −θ′ (§3.4)."""
    for phi_b, th_b, g_b in ((30 * D, 5 * D, 0.0), (-120 * D, 40 * D, 0.3)):
        C_WB = base_wave_dcm(phi_b, th_b, g_b)
        to_aircraft = np.array([np.cos(phi_b) * np.cos(th_b), np.sin(phi_b) * np.cos(th_b), np.sin(th_b)])
        np.testing.assert_allclose(C_WB[:, 0], -to_aircraft, atol=1e-15)
        # the seed's printed middle factor (Ry(+θ′)ᵀ) points u above the horizon: wrong for θ′ > 0
        def ry(a):
            return np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])

        def rz(a):
            return np.array([[np.cos(a), np.sin(a), 0], [-np.sin(a), np.cos(a), 0], [0, 0, 1]])

        u_printed = (rz(phi_b + np.pi).T @ ry(th_b).T)[:, 0]
        assert u_printed[2] == pytest.approx(+np.sin(th_b))
        assert not np.allclose(u_printed, -to_aircraft)


def test_snapshot_statistics():
    rng = np.random.default_rng(4)
    phi, th, g, eta = 30 * D, 20 * D, 15 * D, 27 * D
    S = simulate_snapshots(phi, th, g, eta, 10.0, 200_000, rng, power=2.0)
    A = steering_vector(phi, th, g, eta)
    R = 2.0 * np.outer(A, A.conj()) + 0.2 * np.eye(3)
    Rh = sample_covariance(S)
    np.testing.assert_allclose(Rh, R, atol=0.02)
    # circular: E[S Sᵀ] = 0
    assert np.max(np.abs(S.T @ S / len(S))) < 0.02
    Sb = simulate_snapshots(phi, th, g, eta, 10.0, 50, rng, runs=7)
    assert Sb.shape == (7, 50, 3) and sample_covariance(Sb).shape == (7, 3, 3)


def test_base_geometry_and_frames():
    lat, lon = 32 * D, 118.8 * D
    rm, rn = radii(lat)
    # aircraft 20 km South of the base, 1000 m up
    b, e, r, M = base_geometry(lat, lon, 0.0, lat - 20000 / rm, lon, 1000.0)
    assert b == pytest.approx(np.pi, abs=1e-9)
    assert e == pytest.approx(np.arctan2(1000, 20000), abs=2e-3)  # Earth curvature lowers it slightly
    assert r == pytest.approx(np.hypot(20000, 1000), rel=1e-3)
    # rotation between the two ENU frames: about East by the latitude difference
    ang = np.arccos(np.clip((np.trace(M) - 1) / 2, -1, 1))
    assert ang == pytest.approx(20000 / rm, rel=1e-6)
    np.testing.assert_allclose(enu_rotation_between(lat, lon, lat, lon), np.eye(3), atol=1e-15)
