"""The RTS smoother of the engine's closed-loop filters: the backward pass over the node matrices the
forward pass kept (:func:`rts`: the smoothed error state and covariance per node, nothing passed back
across a re-initialisation) and the smoothed corrections applied to the forward outputs between nodes
(:func:`smooth_outputs`). States and units as the engine's (:mod:`aidnav.filters.layout`: attitude error
[rad], velocity [m/s], position δL, δλ [rad], δh [m], then the sensor and calibration states)."""

from __future__ import annotations

import numpy as np

from aidnav.jit import njit

from .engine import feedback
from .kalman import rts_gain
from .layout import NAV


@njit(cache=True)
def rts(S_post, S_prior, S_phi, S_dx, brk):
    """Backward RTS pass over the nodes of a closed-loop filter: ds (K, n), the smoothed error of the
    post-update nominal at each node, and Ps (K, n, n); ds_k = A_k (ds_{k+1} + dx_{k+1}),
    Ps_k = P⁺_k + A_k (Ps_{k+1} − P⁻_{k+1}) A_kᵀ. ``brk``: first node after a re-initialisation (or −1);
    nothing is passed backwards across it (the states before it are not linearly related)."""
    K, n = S_post.shape[0], S_post.shape[1]
    ds, Ps = np.zeros((K, n)), np.empty((K, n, n))
    Ps[K - 1] = S_post[K - 1]
    for k in range(K - 2, -1, -1):
        if k + 1 == brk:
            ds[k], Ps[k] = 0.0, S_post[k]
            continue
        A = rts_gain(S_post[k], S_phi[k + 1], S_prior[k + 1])
        ds[k] = A @ (ds[k + 1] + S_dx[k + 1])
        Pk = S_post[k] + A @ (Ps[k + 1] - S_prior[k + 1]) @ A.T
        Ps[k] = 0.5 * (Pk + Pk.T)
    return ds, Ps


@njit(cache=True)
def smooth_outputs(out_idx, out_st, out_bias, out_node, node_idx, ds, S_dx, nstate):
    """Apply the smoothed corrections to the forward outputs (linear in time between nodes)."""
    n_out, K = out_idx.shape[0], node_idx.shape[0]
    st, dx, b = np.empty(10), np.empty(nstate), np.empty(max(nstate - NAV, 1))
    res_st, res_b = out_st.copy(), out_bias.copy()
    for o in range(n_out):
        j, k = out_node[o], out_idx[o]
        if j < 0:
            dx[:] = ds[0] + S_dx[0]
        elif j >= K - 1:
            dx[:] = ds[K - 1]
        else:
            k0, k1 = node_idx[j], node_idx[j + 1]
            a = (k - k0) / (k1 - k0) if k1 > k0 else 0.0
            dx[:] = (1.0 - a) * ds[j] + a * (ds[j + 1] + S_dx[j + 1])
            if k == k0:
                dx[:] = ds[j]
        st[:] = out_st[o]
        for i in range(nstate - NAV):
            b[i] = out_bias[o, i]
        feedback(st, b, dx, nstate)
        res_st[o] = st
        for i in range(nstate - NAV):
            res_b[o, i] = b[i]
    return res_st, res_b
