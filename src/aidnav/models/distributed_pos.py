"""The distributed-POS error model shared by the simulator (:mod:`aidnav.sim.distributed_pos`) and the
transfer-alignment filter (:mod:`aidnav.filters.transfer`), seed 004: master POS accuracy, wing flexure
as a second-order Gauss-Markov process (its exact transition and autocorrelation). It describes;
it neither simulates nor estimates.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from aidnav.jit import njit
from aidnav.units import DEG

__all__ = ["BETA_FACTOR", "GNSS_BASELINE_ACCURACY_M", "MasterPosSpec", "FlexureSpec", "flexure_transition",
           "flexure_autocorrelation"]

BETA_FACTOR = 2.146  #: β = 2.146/τ makes τ the 1/e time of R(t) = σ²(1+β|t|)e^{−β|t|} (§5.1 item 7)

#: seed Table 7: GNSS baseline [km] -> (horizontal, vertical) 1σ position accuracy [m]
GNSS_BASELINE_ACCURACY_M: dict[float, tuple[float, float]] = {20.0: (0.1, 0.2), 40.0: (0.5, 1.0),
                                                             60.0: (1.0, 2.0)}


# ------------------------------------------------------------------------------------------ specs
@dataclass(frozen=True)
class MasterPosSpec:
    """1σ white errors of the master POS output (POS/AV610 real-time accuracy by default, §5.1).

    sigma_roll_deg, sigma_pitch_deg, sigma_heading_deg [deg]; sigma_vel_m_s [m/s] per ENU axis;
    sigma_horizontal_m (E and N), sigma_vertical_m [m]; rate_hz: output (= filter) rate [Hz].
    corr_time_s: 0 (default) for white errors, as the seed's "measurement noise" and §5.1's R;
    > 0 for first-order Gauss-Markov errors with that correlation time [s] and the same stationary σ
    (a real POS's errors are slowly varying; used as a sensitivity case, the filter still assumes
    white noise).

    Position drift (the GNSS-baseline-dependent part): a fraction ``pos_drift_fraction`` of each
    position variance is a smooth second-order Gauss-Markov drift d(t) with 1/e time
    ``pos_drift_tau_s`` [s] (the slowly varying residual of differential GNSS: ionosphere,
    troposphere and orbit errors decorrelating with the baseline), the rest white. A POS's velocity is
    consistent with its position, so the master's velocity error carries ḋ(t) (σ = β·σ_d, β = 2.146/τ)
    beside its white ``sigma_vel_m_s``. Default: half the variance, τ = 300 s (the seed states neither;
    at 20 km ḋ is 0.0005 m/s, at 60 km 0.005 m/s horizontal). ``pos_drift_fraction = 0`` gives white
    position errors only.
    """

    sigma_roll_deg: float = 0.005
    sigma_pitch_deg: float = 0.005
    sigma_heading_deg: float = 0.02
    sigma_vel_m_s: float = 0.03
    sigma_horizontal_m: float = 0.1
    sigma_vertical_m: float = 0.2
    rate_hz: float = 1.0
    corr_time_s: float = 0.0
    pos_drift_fraction: float = 0.5
    pos_drift_tau_s: float = 300.0

    def __post_init__(self):
        if not 0.0 <= self.pos_drift_fraction <= 1.0:
            raise ValueError("MasterPosSpec: pos_drift_fraction must be in [0, 1]")
        if self.pos_drift_tau_s <= 0:
            raise ValueError("MasterPosSpec: pos_drift_tau_s must be > 0 [s]")

    @classmethod
    def for_gnss_baseline(cls, baseline_km: float, **kw) -> MasterPosSpec:
        """Master accuracy for a GNSS baseline of seed Table 7 (20, 40 or 60 km): the master's position
        accuracy is taken equal to the GNSS accuracy (as the seed assumes); the rest as POS/AV610."""
        key = float(baseline_km)
        if key not in GNSS_BASELINE_ACCURACY_M:
            raise ValueError(f"MasterPosSpec.for_gnss_baseline: baseline {baseline_km} km not in seed "
                             f"Table 7 ({', '.join(f'{k:g}' for k in GNSS_BASELINE_ACCURACY_M)} km)")
        hor, ver = GNSS_BASELINE_ACCURACY_M[key]
        return cls(sigma_horizontal_m=hor, sigma_vertical_m=ver, **kw)

    @property
    def att_sigma_rad(self) -> np.ndarray:
        """(roll, pitch, heading) 1σ [rad]."""
        return np.array([self.sigma_roll_deg, self.sigma_pitch_deg, self.sigma_heading_deg]) * DEG

    @property
    def pos_sigma_m(self) -> np.ndarray:
        """(E, N, U) 1σ [m]."""
        return np.array([self.sigma_horizontal_m, self.sigma_horizontal_m, self.sigma_vertical_m])

    @property
    def pos_drift_sigma_m(self) -> np.ndarray:
        """(E, N, U) 1σ of the smooth position drift [m]."""
        return self.pos_sigma_m * math.sqrt(self.pos_drift_fraction)

    @property
    def vel_drift_sigma_m_s(self) -> np.ndarray:
        """(E, N, U) 1σ of the drift's rate ḋ carried by the master velocity [m/s]."""
        return self.pos_drift_sigma_m * BETA_FACTOR / self.pos_drift_tau_s


@dataclass(frozen=True)
class FlexureSpec:
    """Wing flexure: second-order Gauss-Markov per body axis (x, y, z), σ [deg] and 1/e time τ [s]."""

    sigma_deg: tuple[float, float, float] = (0.01, 0.15, 0.01)
    tau_s: tuple[float, float, float] = (2.0, 5.0, 2.0)

    def __post_init__(self):
        if len(self.sigma_deg) != 3 or len(self.tau_s) != 3:
            raise ValueError("FlexureSpec: sigma_deg and tau_s need 3 values (x, y, z)")
        if min(self.tau_s) <= 0 or min(self.sigma_deg) < 0:
            raise ValueError("FlexureSpec: tau_s must be > 0 and sigma_deg >= 0")

    @property
    def sigma(self) -> np.ndarray:
        """σ_J [rad]."""
        return np.asarray(self.sigma_deg, float) * DEG

    @property
    def tau(self) -> np.ndarray:
        """τ_J [s]."""
        return np.asarray(self.tau_s, float)

    @property
    def beta(self) -> np.ndarray:
        """β_J = 2.146/τ_J [1/s]."""
        return BETA_FACTOR / self.tau

    @property
    def q_eta(self) -> np.ndarray:
        """PSD of the driving noise Q_ηJ = 4β³σ² [rad²/s³]."""
        return 4.0 * self.beta**3 * self.sigma**2


# --------------------------------------------------------------------------------------- flexure
@njit(cache=True)
def flexure_transition(beta, sigma, dt):
    """Exact (Φ, Qd) (2×2 each) of one second-order Markov axis [θ, θ̇] over ``dt`` [s].

    beta [1/s], sigma [rad]. Φ = e^{−βdt}[[1+βdt, dt], [−β²dt, 1−βdt]]; Qd = P∞ − Φ P∞ Φᵀ with
    P∞ = diag(σ², β²σ²) (exact for the stationary process; the module docstring has the derivation).
    """
    e = np.exp(-beta * dt)
    phi = np.empty((2, 2))
    phi[0, 0] = e * (1.0 + beta * dt)
    phi[0, 1] = e * dt
    phi[1, 0] = -e * beta * beta * dt
    phi[1, 1] = e * (1.0 - beta * dt)
    pinf = np.zeros((2, 2))
    pinf[0, 0] = sigma * sigma
    pinf[1, 1] = beta * beta * sigma * sigma
    qd = pinf - phi @ pinf @ phi.T
    qd = 0.5 * (qd + qd.T)
    return phi, qd


def flexure_autocorrelation(spec: FlexureSpec, lags) -> np.ndarray:
    """Theoretical autocorrelation R(t) = σ²(1 + β|t|)e^{−β|t|} [rad²], (len(lags), 3)."""
    t = np.abs(np.asarray(lags, float))[:, None]
    b = spec.beta[None, :]
    return spec.sigma[None, :] ** 2 * (1.0 + b * t) * np.exp(-b * t)
