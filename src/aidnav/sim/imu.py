"""IMU error model: corrupt exact IMU increments with biases, noise, scale factor, misalignment, quantisation.

Frames and units (``docs/conventions.md``): body frame b = RFU; increments Δθ [rad] and Δv [m/s] over
(t_{k-1}, t_k], time-tagged at t_k. :class:`ImuSpec` holds **SI units** (rad/s, m/s², rad/√s, m/s/√s,
s, dimensionless ratios, rad); the boundary units (deg/h, deg/√h, µg, m/s/√h, ppm, arcsec) are accepted
by :meth:`ImuSpec.from_units` and :meth:`ImuSpec.from_config` and given back by :meth:`ImuSpec.to_units`.

Error model, per sensor triad (gyro shown; the accelerometer triad is the same with Δv):

    Δθ̃_k = Q[ (I + S + M) Δθ_k + (b + b_GM(t_k) + b_RW(t_k)) Δt_k + σ_ARW √Δt_k n_k ]

* ``b``: turn-on constant bias [rad/s]; drawn per run from N(0, σ_b²) per axis (``bias_mode="random"``,
  default) or used as given (``bias_mode="fixed"``).
* ``b_GM``: first-order Gauss-Markov bias instability with stationary σ [rad/s] and correlation time τ [s],
  exact discretisation b_k = e^{-Δt/τ} b_{k-1} + σ √(1 - e^{-2Δt/τ}) w_k, started from its stationary
  distribution; it is held constant over each interval at its value at t_k.
* ``b_RW``: rate random walk b_k = b_{k-1} + σ_RRW √Δt_k w_k [σ_RRW in rad/s/√s], starting at 0.
* ``σ_ARW``: angle random walk (white rate noise density) [rad/√s]: an increment gets σ_ARW √Δt noise.
* ``S = diag(s)``: scale-factor errors, s ~ N(0, σ_s²) per axis [-] (ppm · 1e-6).
* ``M``: small-angle axis misalignment / non-orthogonality, zero diagonal, each of the six off-diagonal
  entries ~ N(0, σ_m²) [rad].
* ``Q``: quantisation to multiples of the quantum q [rad] (or [m/s]) with residual carry: the part
  lost by rounding is added to the next sample (unbiased). The residual carried into the first sample
  is uniform in [-q/2, q/2), so the running sum of the output equals the running sum of the input plus
  r_0 - r_k, within q.

All random numbers are drawn from the caller's ``numpy.random.Generator``: the turn-on draws in numpy,
the per-sample unit normals inside the numba kernel (numba's ``Generator.standard_normal``: the same
stream as numpy's ``standard_normal`` on that generator, 18 a sample: white gyro, white accel, GM gyro,
GM accel, RW gyro, RW accel). The draws are made in a fixed order whatever the spec, so the same seed
gives the same unit-variance draws for every grade (common random numbers across grades).
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields, replace
from typing import Any

import numpy as np

from aidnav.data import ImuData
from aidnav.jit import njit

# unit factors (aidnav.units), re-exported: sensor specs below are written with them
from aidnav.units import (  # noqa: E402, F401
    ARCSEC,
    DEG,
    DEG_H,
    DEG_H_SQRT_H,
    DEG_SQRT_H,
    M_S_SQRT_H,
    PPM,
    UG,
    UG_SQRT_H,
)


def _vec3(x, name: str) -> np.ndarray:
    a = np.asarray(x, dtype=float)
    if a.ndim == 0:
        a = np.full(3, float(a))
    if a.shape != (3,):
        raise ValueError(f"ImuSpec.{name}: expected a scalar or 3 values, got shape {a.shape}")
    if not np.all(np.isfinite(a)) and name not in ("gyro_bias_tau", "accel_bias_tau"):
        raise ValueError(f"ImuSpec.{name}: values must be finite")
    return a.copy()


def _z3():
    return np.zeros(3)


@dataclass
class ImuSpec:
    """IMU error specification in SI units (per axis of the body RFU frame; (3,) arrays or scalars).

    Attributes
    ----------
    gyro_bias : turn-on constant gyro bias: 1σ [rad/s] (``bias_mode="random"``) or the value [rad/s]
        (``bias_mode="fixed"``).
    accel_bias : same for the accelerometers [m/s²].
    bias_mode : ``"random"`` (draw N(0, σ²) per run and axis) or ``"fixed"`` (use the values as given).
    gyro_bias_instability, accel_bias_instability : stationary 1σ of the first-order Gauss-Markov bias
        [rad/s], [m/s²] (the "bias instability" number is used as this σ).
    gyro_bias_tau, accel_bias_tau : Gauss-Markov correlation times [s] (> 0; ``inf`` = random constant).
    gyro_arw : angle random walk (white rate noise density) [rad/√s].
    accel_vrw : velocity random walk (white specific-force noise density) [m/s/√s].
    gyro_rrw : rate random walk [rad/s/√s]; accel_rrw : acceleration random walk [m/s²/√s].
    gyro_scale, accel_scale : scale-factor error 1σ [-] (ratio; 1 ppm = 1e-6).
    gyro_misalignment, accel_misalignment : 1σ of each off-diagonal entry of the small-angle
        misalignment / non-orthogonality matrix M [rad].
    gyro_quant : angle quantum [rad]; accel_quant : velocity quantum [m/s] (0 = none).
    name : label (the preset name or ``"custom"``).
    """

    gyro_bias: np.ndarray = field(default_factory=_z3)
    accel_bias: np.ndarray = field(default_factory=_z3)
    bias_mode: str = "random"
    gyro_bias_instability: np.ndarray = field(default_factory=_z3)
    accel_bias_instability: np.ndarray = field(default_factory=_z3)
    gyro_bias_tau: np.ndarray = field(default_factory=lambda: np.full(3, 3600.0))
    accel_bias_tau: np.ndarray = field(default_factory=lambda: np.full(3, 3600.0))
    gyro_arw: np.ndarray = field(default_factory=_z3)
    accel_vrw: np.ndarray = field(default_factory=_z3)
    gyro_rrw: np.ndarray = field(default_factory=_z3)
    accel_rrw: np.ndarray = field(default_factory=_z3)
    gyro_scale: np.ndarray = field(default_factory=_z3)
    accel_scale: np.ndarray = field(default_factory=_z3)
    gyro_misalignment: np.ndarray = field(default_factory=_z3)
    accel_misalignment: np.ndarray = field(default_factory=_z3)
    gyro_quant: float = 0.0
    accel_quant: float = 0.0
    name: str = "custom"

    _VEC = ("gyro_bias", "accel_bias", "gyro_bias_instability", "accel_bias_instability", "gyro_bias_tau",
            "accel_bias_tau", "gyro_arw", "accel_vrw", "gyro_rrw", "accel_rrw", "gyro_scale",
            "accel_scale", "gyro_misalignment", "accel_misalignment")

    def __post_init__(self):
        for n in self._VEC:
            setattr(self, n, _vec3(getattr(self, n), n))
        for n in self._VEC:
            if n not in ("gyro_bias", "accel_bias") and np.any(getattr(self, n) < 0):
                raise ValueError(f"ImuSpec.{n}: must be >= 0")
        for n in ("gyro_bias_tau", "accel_bias_tau"):
            if np.any(getattr(self, n) <= 0):
                raise ValueError(f"ImuSpec.{n}: correlation time must be > 0 s (inf for a constant)")
        if self.bias_mode not in ("random", "fixed"):
            raise ValueError(f"ImuSpec.bias_mode: 'random' or 'fixed', got {self.bias_mode!r}")
        if self.bias_mode == "random" and (np.any(self.gyro_bias < 0) or np.any(self.accel_bias < 0)):
            raise ValueError("ImuSpec: a random (σ) constant bias must be >= 0; use bias_mode='fixed'")
        self.gyro_quant = float(self.gyro_quant)
        self.accel_quant = float(self.accel_quant)
        if self.gyro_quant < 0 or self.accel_quant < 0:
            raise ValueError("ImuSpec: quanta must be >= 0")

    def __eq__(self, other):
        if not isinstance(other, ImuSpec):
            return NotImplemented
        return all(np.array_equal(getattr(self, f.name), getattr(other, f.name)) for f in fields(self))

    # ---------------------------------------------------------------------------------- constructors
    @classmethod
    def perfect(cls) -> ImuSpec:
        """An error-free IMU (``corrupt_imu`` returns the input unchanged)."""
        return cls(name="perfect")

    @classmethod
    def from_units(
        cls,
        gyro_bias_deg_h=0.0,
        arw_deg_sqrt_h=0.0,
        accel_bias_ug=0.0,
        vrw_m_s_sqrt_h=0.0,
        gyro_bias_instability_deg_h=0.0,
        accel_bias_instability_ug=0.0,
        bias_corr_time_s=3600.0,
        gyro_rrw_deg_h_sqrt_h=0.0,
        accel_rrw_ug_sqrt_h=0.0,
        gyro_scale_ppm=0.0,
        accel_scale_ppm=0.0,
        misalignment_arcsec=0.0,
        gyro_misalignment_arcsec=None,
        accel_misalignment_arcsec=None,
        gyro_quant_rad=0.0,
        accel_quant_m_s=0.0,
        bias_mode: str = "random",
        name: str = "custom",
    ) -> ImuSpec:
        """Spec from the boundary units of ``docs/conventions.md`` (each value a scalar or 3 per-axis values).

        gyro_bias_deg_h [deg/h], arw_deg_sqrt_h [deg/√h], accel_bias_ug [µg], vrw_m_s_sqrt_h [m/s/√h],
        gyro_bias_instability_deg_h [deg/h], accel_bias_instability_ug [µg] (Gauss-Markov σ),
        bias_corr_time_s [s] (both triads), gyro_rrw_deg_h_sqrt_h [deg/h/√h], accel_rrw_ug_sqrt_h [µg/√h],
        gyro_scale_ppm, accel_scale_ppm [ppm], misalignment_arcsec [arcsec] (both triads unless
        gyro_/accel_misalignment_arcsec is given), gyro_quant_rad [rad], accel_quant_m_s [m/s].
        1 deg/h = π/180/3600 rad/s; 1 µg = 9.80665e-6 m/s²; 1 deg/√h = π/180/60 rad/√s.
        """
        gm = misalignment_arcsec if gyro_misalignment_arcsec is None else gyro_misalignment_arcsec
        am = misalignment_arcsec if accel_misalignment_arcsec is None else accel_misalignment_arcsec
        return cls(
            gyro_bias=np.asarray(gyro_bias_deg_h, float) * DEG_H,
            accel_bias=np.asarray(accel_bias_ug, float) * UG,
            bias_mode=bias_mode,
            gyro_bias_instability=np.asarray(gyro_bias_instability_deg_h, float) * DEG_H,
            accel_bias_instability=np.asarray(accel_bias_instability_ug, float) * UG,
            gyro_bias_tau=bias_corr_time_s,
            accel_bias_tau=bias_corr_time_s,
            gyro_arw=np.asarray(arw_deg_sqrt_h, float) * DEG_SQRT_H,
            accel_vrw=np.asarray(vrw_m_s_sqrt_h, float) * M_S_SQRT_H,
            gyro_rrw=np.asarray(gyro_rrw_deg_h_sqrt_h, float) * DEG_H_SQRT_H,
            accel_rrw=np.asarray(accel_rrw_ug_sqrt_h, float) * UG_SQRT_H,
            gyro_scale=np.asarray(gyro_scale_ppm, float) * PPM,
            accel_scale=np.asarray(accel_scale_ppm, float) * PPM,
            gyro_misalignment=np.asarray(gm, float) * ARCSEC,
            accel_misalignment=np.asarray(am, float) * ARCSEC,
            gyro_quant=gyro_quant_rad,
            accel_quant=accel_quant_m_s,
            name=name,
        )

    @classmethod
    def grade(cls, name: str) -> ImuSpec:
        """Preset IMU grade (1σ values per axis, isotropic). ``name`` is case-insensitive.

        ============== ======= ======= ======== ====== ====== ========= ====== ===== ===== ======= ======
        preset         gyro b  gyro BI ARW      acc b  acc BI VRW       τ_GM   SF g  SF a  misal.  source
                       deg/h   deg/h   deg/√h   µg     µg     m/s/√h    s      ppm   ppm   arcsec
        ============== ======= ======= ======== ====== ====== ========= ====== ===== ===== ======= ======
        navigation     0.005   0.003   0.002    10     5      0.002     3600   5     50    5       [G]
        tactical       1       0.3     0.1      100    50     0.03      600    100   300   60      [G]
        mems           10      5       0.3      1000   100    0.1       300    500   1000  360     [G]
        consumer       360     20      1        10000  500    0.2       100    5000  5000  1800    [G]
        seed004_high   0.01    0       1.67e-4  10     0      5.88e-3   --     0     0     0       [T1]
        seed004_medium 0.05    0       8.33e-4  50     0      2.94e-2   --     0     0     0       [T1]
        seed004_low    0.1     0       1.67e-3  100    0      5.88e-2   --     0     0     0       [T1]
        seed004_sub    0.1     0       1.67e-3  50     0      2.94e-2   --     0     0     0       [S]
        seed000        0.1     0       1.67e-4  500    0      5.88e-2   --     0     0     0       [S0]
        perfect        0       0       0        0      0      0         --     0     0     0       --
        ============== ======= ======= ======== ====== ====== ========= ====== ===== ===== ======= ======

        b: turn-on constant bias σ (drawn per run); BI: Gauss-Markov bias-instability σ with correlation
        time τ_GM (both triads); SF: scale-factor σ; misal.: σ of each off-diagonal misalignment entry
        (both triads). No preset has rate random walk or quantisation (set them with overrides).

        Sources. [G]: representative values inside the ranges that Groves, *Principles of GNSS, Inertial,
        and Multisensor Integrated Navigation Systems* (2nd ed., 2013), §4.4, gives for each grade; the
        brief's anchor numbers (navigation 0.005 deg/h, 0.002 deg/√h, 10 µg; tactical 1 deg/h, 0.1 deg/√h,
        100 µg; MEMS 10 deg/h, 0.3 deg/√h, 1 mg) are used as given; not any one datasheet.
        [T1]: seed 004 Table 1 (models.md §5.1): gyro "constant and random" X deg/h, accelerometer X µg.
        [S]: seed 004 sub-IMU (models.md §5.1): gyro constant and random 0.1 deg/h, accelerometer constant
        50 µg and random 50 µg. [S0]: seed 000 Table 1 (models.md §1.3): gyro constant 0.1 deg/h, random
        0.01 deg/h; accelerometer constant 500 µg, random 100 µg.

        Reading of the seeds' "random" terms: a white-noise **density** with the printed number taken per
        √Hz, i.e. "random X deg/h" = X deg/h/√Hz = X/60 deg/√h of ARW (1 deg/h/√Hz = 1/60 deg/√h), and
        "random Y µg" = Y µg/√Hz = Y·9.80665e-6 m/s²/√Hz = Y·9.80665e-6·60 m/s/√h of VRW. Equivalently: white
        noise whose 1σ at a 1 Hz rate equals the printed number (the PSINS / Qin convention of Q = σ²·1 s).
        The seeds' "constant" terms are the turn-on bias σ, drawn per run (``bias_mode="random"``).
        """
        key = name.strip().lower()
        if key not in _PRESETS:
            raise ValueError(f"ImuSpec.grade: unknown grade {name!r}; known: {', '.join(sorted(_PRESETS))}")
        return cls.from_units(**_PRESETS[key], name=key)

    @classmethod
    def from_config(cls, cfg: Any) -> ImuSpec:
        """Spec from a configuration mapping (dict, or a pydantic model: ``cfg.model_dump()`` is used).

        Keys: ``grade`` (a :meth:`grade` preset name; missing or None = start from an error-free IMU) and
        optional overrides in boundary units, each a scalar or 3 per-axis values: gyro_bias_deg_h,
        arw_deg_sqrt_h, accel_bias_ug, vrw_m_s_sqrt_h, gyro_bias_instability_deg_h,
        accel_bias_instability_ug, bias_corr_time_s, gyro_scale_ppm, accel_scale_ppm, misalignment_arcsec,
        gyro_quant_rad, accel_quant_m_s, ``bias_mode`` ("random"/"fixed"), ``perfect`` (bool: True makes
        every error zero, whatever else is given). Keys whose value is None are ignored. Any other key
        raises ValueError naming it.
        """
        d = _as_dict(cfg)
        unknown = [k for k in d if k not in _CONFIG_KEYS]
        if unknown:
            raise ValueError(f"ImuSpec.from_config: unknown key(s) {', '.join(map(repr, unknown))}; "
                             f"allowed: {', '.join(sorted(_CONFIG_KEYS))}")
        d = {k: v for k, v in d.items() if v is not None}
        if d.get("perfect", False):
            return cls.perfect()
        grade = d.pop("grade", None)
        d.pop("perfect", None)
        key = "custom" if grade is None else str(grade).strip().lower()
        if grade is not None and key not in _PRESETS:
            raise ValueError(f"ImuSpec.from_config: unknown grade {grade!r}; "
                             f"known: {', '.join(sorted(_PRESETS))}")
        base = dict(_PRESETS[key]) if grade is not None else {}
        if "misalignment_arcsec" in d:  # one override for both triads replaces per-triad preset values
            base.pop("gyro_misalignment_arcsec", None)
            base.pop("accel_misalignment_arcsec", None)
        base.update(d)
        return cls.from_units(**base, name=key)

    # ----------------------------------------------------------------------------------- reporting
    @property
    def is_perfect(self) -> bool:
        """True if every error term is zero (a fixed zero bias counts as zero)."""
        terms = [n for n in self._VEC if n not in ("gyro_bias_tau", "accel_bias_tau")]
        zero = all(not np.any(getattr(self, n)) for n in terms)
        return zero and self.gyro_quant == 0.0 and self.accel_quant == 0.0

    def to_units(self) -> dict:
        """The spec in boundary units (keys as :meth:`from_units`; per-axis lists)."""
        return {
            "gyro_bias_deg_h": (self.gyro_bias / DEG_H).tolist(),
            "arw_deg_sqrt_h": (self.gyro_arw / DEG_SQRT_H).tolist(),
            "accel_bias_ug": (self.accel_bias / UG).tolist(),
            "vrw_m_s_sqrt_h": (self.accel_vrw / M_S_SQRT_H).tolist(),
            "gyro_bias_instability_deg_h": (self.gyro_bias_instability / DEG_H).tolist(),
            "accel_bias_instability_ug": (self.accel_bias_instability / UG).tolist(),
            "gyro_bias_corr_time_s": self.gyro_bias_tau.tolist(),
            "accel_bias_corr_time_s": self.accel_bias_tau.tolist(),
            "gyro_rrw_deg_h_sqrt_h": (self.gyro_rrw / DEG_H_SQRT_H).tolist(),
            "accel_rrw_ug_sqrt_h": (self.accel_rrw / UG_SQRT_H).tolist(),
            "gyro_scale_ppm": (self.gyro_scale / PPM).tolist(),
            "accel_scale_ppm": (self.accel_scale / PPM).tolist(),
            "gyro_misalignment_arcsec": (self.gyro_misalignment / ARCSEC).tolist(),
            "accel_misalignment_arcsec": (self.accel_misalignment / ARCSEC).tolist(),
            "gyro_quant_rad": self.gyro_quant,
            "accel_quant_m_s": self.accel_quant,
            "bias_mode": self.bias_mode,
            "name": self.name,
        }

    def copy(self, **changes) -> ImuSpec:
        """A copy with some SI fields replaced (``dataclasses.replace``)."""
        return replace(self, **changes)


def _as_dict(cfg: Any) -> dict:
    if cfg is None:
        return {}
    if hasattr(cfg, "model_dump"):
        cfg = cfg.model_dump()
    if not isinstance(cfg, dict):
        raise TypeError(f"expected a dict or a pydantic model, got {type(cfg).__name__}")
    return dict(cfg)


def _seed_grade(gyro_deg_h, gyro_random_deg_h, accel_ug, accel_random_ug) -> dict:
    """Seed-paper grade: constant σ plus 'random' read as a white-noise density per √Hz (see grade())."""
    return dict(gyro_bias_deg_h=gyro_deg_h, arw_deg_sqrt_h=gyro_random_deg_h / 60.0, accel_bias_ug=accel_ug,
                vrw_m_s_sqrt_h=accel_random_ug * UG * 60.0)


#: columns of the tabulated grades below
_GRADE_KEYS = ("gyro_bias_deg_h", "gyro_bias_instability_deg_h", "arw_deg_sqrt_h", "accel_bias_ug",
               "accel_bias_instability_ug", "vrw_m_s_sqrt_h", "bias_corr_time_s", "gyro_scale_ppm",
               "accel_scale_ppm", "misalignment_arcsec")
_GRADE_TABLE = {
    #              gyro   instab  ARW    accel   instab  VRW    τ [s]   gSF    aSF     misal.
    "navigation": (0.005, 0.003, 0.002, 10.0, 5.0, 0.002, 3600.0, 5.0, 50.0, 5.0),
    "tactical": (1.0, 0.3, 0.1, 100.0, 50.0, 0.03, 600.0, 100.0, 300.0, 60.0),
    "mems": (10.0, 5.0, 0.3, 1000.0, 100.0, 0.1, 300.0, 500.0, 1000.0, 360.0),
    "consumer": (360.0, 20.0, 1.0, 10000.0, 500.0, 0.2, 100.0, 5000.0, 5000.0, 1800.0),
}

_PRESETS: dict[str, dict] = {
    **{name: dict(zip(_GRADE_KEYS, row, strict=True)) for name, row in _GRADE_TABLE.items()},
    "seed004_high": _seed_grade(0.01, 0.01, 10.0, 10.0),
    "seed004_medium": _seed_grade(0.05, 0.05, 50.0, 50.0),
    "seed004_low": _seed_grade(0.1, 0.1, 100.0, 100.0),
    "seed004_sub": _seed_grade(0.1, 0.1, 50.0, 50.0),
    "seed000": _seed_grade(0.1, 0.01, 500.0, 100.0),
    "perfect": dict(),
}

_CONFIG_KEYS = frozenset({
    "grade", "gyro_bias_deg_h", "arw_deg_sqrt_h", "accel_bias_ug", "vrw_m_s_sqrt_h",
    "gyro_bias_instability_deg_h", "accel_bias_instability_ug", "bias_corr_time_s", "gyro_scale_ppm",
    "accel_scale_ppm", "misalignment_arcsec", "gyro_quant_rad", "accel_quant_m_s", "perfect", "bias_mode",
})

GRADES = tuple(_PRESETS)  #: names accepted by :meth:`ImuSpec.grade`


# ------------------------------------------------------------------------------------------ kernel
@njit(cache=True)
def _corrupt_kernel(dth, dv, dt, mat_g, mat_a, b_g, b_a, gm_sig, gm_tau, white, rrw, quant, rng, state,
                    out_g, out_a, drift, keep_drift):
    """Corrupt the samples.

    dth, dv, dt : (n, 3), (n, 3), (n,) true increments [rad], [m/s] and intervals [s].
    mat_g, mat_a : (3, 3) I + S + M.  b_g, b_a : (3,) constant biases [rad/s], [m/s²].
    gm_sig, gm_tau, white, rrw : (6,) gyro then accel GM σ, τ [s], white density, RRW density.
    quant : (2,) quanta [rad], [m/s].  rng : the Generator of the 18 unit normals of each sample (white g,
    white a, GM g, GM a, RW g, RW a).
    state : (3, 6) GM state, RW state, quantisation residual (gyro then accel), updated in place.
    out_g, out_a : (n, 3) outputs. drift : (n, 6) time-varying bias (GM + RW) at t_k if keep_drift.
    """
    n = dth.shape[0]
    # the factors of an interval length h (exp, square roots), computed again only when h changes: the
    # same values as computing them at every sample
    h_last, sh = np.nan, 0.0
    g_fac, r_fac, w_fac, phis, z = np.empty(6), np.empty(6), np.empty(6), np.empty(6), np.empty(18)
    drs = np.empty(6)
    for k in range(n):
        for j in range(18):
            z[j] = rng.standard_normal()
        h = dt[k]
        if h != h_last:
            h_last, sh = h, np.sqrt(h)
            for c in range(6):
                phis[c] = np.exp(-h / gm_tau[c])
                g_fac[c] = gm_sig[c] * np.sqrt(max(0.0, 1.0 - phis[c] * phis[c]))
                r_fac[c] = rrw[c] * sh
                w_fac[c] = white[c] * sh
        # Gauss-Markov and random-walk states (gyro then accel), then each triad's samples
        for c in range(6):
            state[0, c] = phis[c] * state[0, c] + g_fac[c] * z[6 + c]
            state[1, c] += r_fac[c] * z[12 + c]
            dr = state[0, c] + state[1, c]
            drs[c] = dr
            if keep_drift:
                drift[k, c] = dr
        _triad(dth, k, mat_g, b_g, drs, w_fac, z, h, quant[0], state, out_g, 0)
        _triad(dv, k, mat_a, b_a, drs, w_fac, z, h, quant[1], state, out_a, 3)


@njit(cache=True, inline="always")
def _triad(inc, k, mat, b, drs, w_fac, z, h, q, state, out, c0):
    """Sample k of one triad (columns c0..c0+2 of the (6,) factors and states): the error model on the
    true increments ``inc[k]``, quantised with residual carry, into ``out[k]`` (element by element: no
    array views in the per-sample loop)."""
    for i in range(3):
        c = c0 + i
        x = mat[i, 0] * inc[k, 0] + mat[i, 1] * inc[k, 1] + mat[i, 2] * inc[k, 2]
        x += (b[i] + drs[c]) * h + w_fac[c] * z[c]
        if q > 0.0:
            y = x + state[2, c]
            xq = np.floor(y / q + 0.5) * q
            state[2, c] = y - xq
            x = xq
        out[k, i] = x


def _intervals(imu: ImuData) -> np.ndarray:
    t = imu.time
    if len(t) == 0:
        return np.zeros(0)
    t0 = imu.t0
    if t0 is None:
        raise ValueError("corrupt_imu: ImuData.t0 is needed to know the first interval")
    dt = np.diff(np.concatenate(([t0], t)))
    if np.any(dt <= 0):
        raise ValueError("corrupt_imu: sample times must be strictly increasing")
    return dt


def corrupt_imu(imu: ImuData, spec: ImuSpec, rng: np.random.Generator,
                return_drift: bool = False, out=None) -> tuple[ImuData, dict]:
    """Add the errors of ``spec`` to exact IMU increments.

    Parameters
    ----------
    imu : true increments Δθ [rad], Δv [m/s], body RFU, over (t_{k-1}, t_k] (t_{-1} = ``imu.t0``);
        non-uniform intervals are allowed (each sample uses its own Δt_k).
    spec : error model in SI units (see module docstring for the equation).
    rng : the random generator (its state advances).
    return_drift : also return the time-varying bias (Gauss-Markov + random walk) at each t_k.
    out : optional (Δθ, Δv) C-contiguous (N, 3) arrays to write the corrupted increments into (the
        returned ImuData holds them), e.g. rows of a Monte Carlo batch's (R, N, 3) arrays.

    Returns
    -------
    (ImuData, realised) : corrupted increments (same times, t0, events plus one note) and a dict of the
    realised turn-on constants: ``gyro_bias`` (3,) [rad/s], ``accel_bias`` (3,) [m/s²], ``gyro_scale``,
    ``accel_scale`` (3,) [-], ``gyro_misalignment``, ``accel_misalignment`` (3, 3) [rad] (zero diagonal),
    ``gyro_matrix``, ``accel_matrix`` (3, 3) = I + diag(scale) + misalignment (maps true to measured),
    ``gyro_bias_gm0``, ``accel_bias_gm0`` (3,) initial Gauss-Markov states [rad/s], [m/s²] at ``imu.t0``;
    with ``return_drift``: ``gyro_drift`` (N, 3) [rad/s], ``accel_drift`` (N, 3) [m/s²] (GM + RRW at t_k,
    excluding the constant bias). A perfect spec returns copies of the input with zero constants.
    """
    dt = _intervals(imu)
    n = len(imu)
    # turn-on draws, fixed order: constant bias (6), scale (6), misalignment (18), GM init (6), residual (6)
    zb = rng.standard_normal(6)
    zs = rng.standard_normal(6)
    zm = rng.standard_normal((2, 3, 3))
    zg = rng.standard_normal(6)
    ur = rng.uniform(-0.5, 0.5, 6)

    if spec.bias_mode == "random":
        b_g, b_a = spec.gyro_bias * zb[:3], spec.accel_bias * zb[3:]
    else:
        b_g, b_a = spec.gyro_bias.copy(), spec.accel_bias.copy()
    s_g, s_a = spec.gyro_scale * zs[:3], spec.accel_scale * zs[3:]
    off = 1.0 - np.eye(3)
    m_g = spec.gyro_misalignment[:, None] * zm[0] * off  # row i: σ of sensor axis i
    m_a = spec.accel_misalignment[:, None] * zm[1] * off
    np.fill_diagonal(m_g, 0.0)
    np.fill_diagonal(m_a, 0.0)
    mat_g = np.eye(3) + np.diag(s_g) + m_g
    mat_a = np.eye(3) + np.diag(s_a) + m_a
    gm_sig = np.concatenate((spec.gyro_bias_instability, spec.accel_bias_instability))
    gm_tau = np.concatenate((spec.gyro_bias_tau, spec.accel_bias_tau))
    white = np.concatenate((spec.gyro_arw, spec.accel_vrw))
    rrw = np.concatenate((spec.gyro_rrw, spec.accel_rrw))
    quant = np.array([spec.gyro_quant, spec.accel_quant])
    state = np.zeros((3, 6))
    state[0] = gm_sig * zg
    state[2] = np.repeat(quant, 3) * ur
    realised = {
        "gyro_bias": b_g, "accel_bias": b_a, "gyro_scale": s_g, "accel_scale": s_a,
        "gyro_misalignment": m_g, "accel_misalignment": m_a, "gyro_matrix": mat_g, "accel_matrix": mat_a,
        "gyro_bias_gm0": state[0, :3].copy(), "accel_bias_gm0": state[0, 3:].copy(),
    }

    out_g, out_a = (np.empty((n, 3)), np.empty((n, 3))) if out is None else out
    drift = np.zeros((n if return_drift else 1, 6))
    _corrupt_kernel(imu.dtheta, imu.dv, dt, mat_g, mat_a, b_g, b_a, gm_sig, gm_tau, white, rrw, quant, rng,
                    state, out_g, out_a, drift, return_drift)
    if return_drift:
        realised["gyro_drift"] = drift[:, :3]
        realised["accel_drift"] = drift[:, 3:]
    events = list(imu.events) + [f"IMU errors simulated: grade {spec.name!r}, bias_mode {spec.bias_mode!r}"]
    return ImuData(imu.time.copy(), out_g, out_a, t0=imu.t0, events=events), realised


__all__ = ["ImuSpec", "corrupt_imu", "GRADES", "DEG_H", "DEG_SQRT_H", "UG", "M_S_SQRT_H", "PPM", "ARCSEC"]
