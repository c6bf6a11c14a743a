"""The engine's one update-with-gate policy (:mod:`aidnav.filters.engine`'s module doc): the χ² gate by the
number of rows, the acceptance after consecutive rejections, and (:func:`policy_update`) the
re-initialisation after consecutive rejections or an NIS window far out of its χ² band (the covariance
scaling itself: :mod:`.reinit`). Innovations in the measurement models' units, NIS dimensionless."""

from __future__ import annotations

import numpy as np

from aidnav.jit import njit

from .kalman import update
from .reinit import chi2_quantile, inflate, nis_of, scale_nav

__all__ = ["WIN_MAX", "Z_999", "gated_update", "policy_update"]

WIN_MAX = 64  # longest NIS window
Z_999 = 3.090232  # standard normal quantile of 0.999 (the re-initialisation test's χ² band)


@njit(cache=True)
def gated_update(x, P, wk, m, model, mod, rej, log, li):
    """The update policy: χ² gate ``mod.gate[model, m]`` unless ``mod.max_rej[model]`` consecutive
    rejections; writes status, NIS, innovation and diag S to log row ``li``. Returns accepted."""
    gate = 0.0 if rej[model] >= mod.max_rej[model] else mod.gate[model, m]
    nu, sd = np.zeros(m), np.zeros(m)
    ok, nis = update(x, P, wk.H[:m].copy(), wk.R[:m, :m].copy(), wk.z[:m].copy(), gate, nu, sd)
    rej[model] = 0 if ok else rej[model] + 1
    log.status[li], log.nis[li], log.nu[li, :m], log.s[li, :m] = (1 if ok else 0), nis, nu, sd
    return ok


@njit(cache=True)
def policy_update(x, P, wk, m, model, mod, rej, win, log, li):
    """:func:`gated_update` with the re-initialisation (module doc): after ``mod.max_rej[model]``
    consecutive rejections, or when the last ``mod.win_n[model]`` accepted NIS (this one included; ``win``
    (N_MODELS, WIN_MAX + 2): the values, then count and ring position) sum above the 99.9 % χ²(Σ m)
    quantile, P's navigation block is inflated (:func:`.reinit.inflate_nav`) and the update is made
    ungated. A model with ``win_n`` −1 (an aid that sees only part of the motion: odometer speed,
    barometric height) never inflates: after ``max_rej`` rejections its update is accepted ungated,
    nothing more."""
    H, R, z = wk.H[:m].copy(), wk.R[:m, :m].copy(), wk.z[:m].copy()
    nw = mod.win_n[model]
    why = 1 if rej[model] >= mod.max_rej[model] else 0
    gate = mod.gate[model, m]
    # the pre-update NIS is computed here only when the window or a re-initialisation needs it before the
    # update; otherwise the update's own NIS (the same νᵀS⁻¹ν) is logged
    nis0 = nis_of(x, P, H, R, z) if (nw > 0 or why > 0) else -1.0
    if why == 0 and nw > 0 and (gate <= 0.0 or nis0 <= gate):
        c, pos = int(win[model, WIN_MAX]), int(win[model, WIN_MAX + 1])
        win[model, pos] = nis0
        win[model, WIN_MAX + 1] = (pos + 1) % nw
        c = min(c + 1, nw)
        win[model, WIN_MAX] = c
        if c == nw and win[model, :nw].sum() > chi2_quantile(nw * m, Z_999):
            why = 2
    if why == 2:  # the window's innovations are λ times larger than S says: P's blocks scaled by λ
        scale_nav(P, win[model, :nw].sum() / (nw * m), mod.cal)
    elif why > 0 and nw >= 0:
        inflate(x, P, H, R, z, mod.cal)
    if why > 0 and nw >= 0:
        win[model, WIN_MAX], win[model, WIN_MAX + 1] = 0.0, 0.0
        log.reinit[li] = why
    nu, sd = np.zeros(m), np.zeros(m)
    ok, nis = update(x, P, H, R, z, 0.0 if why > 0 else gate, nu, sd)
    rej[model] = 0 if ok else rej[model] + 1
    log.nis[li] = nis0 if nis0 >= 0.0 else nis
    log.status[li], log.nu[li, :m], log.s[li, :m] = (1 if ok else 0), nu, sd
    return ok
