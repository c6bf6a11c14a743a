"""Finite-difference check of a measurement model's Jacobian (used by the tests of every model and
available to anyone adding one): H of ``model`` against central differences of its own innovation
z(δx) when the error state δx is fed back into the navigation state (:func:`aidnav.filters.engine.feedback`).
"""

from __future__ import annotations

import numpy as np

from . import MAX_ROWS


def check_jacobian(model, row, par, lay, st0, b0, nav_of, steps, feedback, allow=None):
    """Compare ``H`` of ``model(nav, row, par, lay, H, z, R)`` at (st0, b0) with central differences.

    nav_of(st, b) → the model's ``Nav`` at a perturbed state; steps (n,) the finite-difference steps
    per error state; feedback(st, b, dx, n) applies an error estimate (closed loop). The comparison
    is of H·ε against the response of z to a step ε, with a tolerance relative to the largest
    response per column and row (``allow``: an extra absolute tolerance (m, n)). Returns (H, R, z) of
    the nominal call; raises AssertionError naming the entries that differ."""
    n = len(steps)
    H = np.zeros((MAX_ROWS, n))
    z = np.zeros(MAX_ROWS)
    R = np.zeros((MAX_ROWS, MAX_ROWS))
    m = model(nav_of(st0, b0), row, par, lay, H, z, R)
    assert m > 0, "the model gave no rows at the nominal state"
    Hm = H[:m].copy()

    def z_of(st, b):
        Hj, zj = np.zeros((MAX_ROWS, n)), np.zeros(MAX_ROWS)
        assert model(nav_of(st, b), row, par, lay, Hj, zj, R) == m
        return zj[:m].copy()

    D = step_response(z_of, st0, b0, steps, feedback).T  # (m, n): response to a step of steps[j]
    resp = Hm * steps
    tol = 1e-4 * np.abs(D).max(axis=0, keepdims=True) + 1e-6 * np.abs(D).max(axis=1, keepdims=True) + 1e-15
    if allow is not None:
        tol = tol + allow
    bad = np.abs(resp - D) > tol
    assert not bad.any(), f"H differs at {np.argwhere(bad).tolist()}: H·ε {resp[bad]}, finite diff {D[bad]}"
    return Hm, R[:m, :m].copy(), z[:m].copy()


def step_response(z_of, st0, b0, steps, feedback):
    """Central-difference response of a model's innovation to each error state: row j is
    −(z(+εⱼ) − z(−εⱼ))/2 with the step εⱼ = ``steps[j]`` fed back into (st0, b0) by ``feedback`` (the
    innovation after the feedback is ν − h·δx, so the response is h·ε for a correct Jacobian h).
    ``z_of(st, b)`` → the innovation (scalar or (m,)) at a perturbed state. Returns (n,) or (n, m)."""
    n = len(steps)
    out = []
    for j in range(n):
        zz = []
        for sgn in (1.0, -1.0):
            st, b = st0.copy(), b0.copy()
            dx = np.zeros(n)
            dx[j] = sgn * steps[j]
            feedback(st, b, dx, n)
            zz.append(np.asarray(z_of(st, b), float))
        out.append(-(zz[0] - zz[1]) / 2.0)
    return np.array(out)
