"""GPS satellite orbits, clocks and signal-path models (numba): broadcast ephemeris, Sagnac, DOP,
Klobuchar ionosphere, Saastamoinen troposphere.

Frames and units: e = ECEF WGS-84 [m, m/s]; n = ENU of the receiver; angles [rad]; times are GPS
seconds counted from the start of a *reference week* (the week of the data's first epoch, so that a
log crossing a week end stays increasing): ``t = (week − ref_week)·604800 + sow``.

Ephemeris records are rows of a float64 array (column indices ``E_*`` below), so that kernels can
take a whole table: broadcast ephemerides from RINEX (:mod:`aidnav.io.rinex`) and the Keplerian
almanac-like orbits of the simulated constellation (:mod:`aidnav.sim.gnss_constellation`, the same
format with zero harmonic terms) go through the same code.

Satellite state (:func:`eph_state`, IS-GPS-200 Table 20-IV, with the analytic time derivative):
position and velocity in the ECEF frame *of the transmit time* (not rotated), satellite clock offset
dt_s = a_f0 + a_f1 Δt + a_f2 Δt² + Δt_r with the relativistic term Δt_r = F e √A sin E_k
(F = −4.442807633e-10 s/√m), and its rate. The group delay T_GD is **not** applied here (L1 C/A users
subtract it: :func:`sat_from_pseudorange` does when asked).

Signal path (:func:`geo_range`): the range from a satellite position at transmit time (ECEF of transmit
time) to a receiver at receive time (ECEF of receive time) is |r_s − r_r| + ω_e (x_s y_r − y_s x_r)/c,
the first-order Sagnac (Earth-rotation) correction (≤ 30 m; the neglected second order is < 1 mm);
its rate adds ω_e/c (v_sy x_r + y_s v_rx − v_sx y_r − x_s v_ry) to e·(v_s − v_r).

**Every constellation** (issue 40). A satellite is one integer id ``100·system + PRN`` with the systems
G = 0 (GPS), E = 1 (Galileo), C = 2 (BeiDou), R = 3 (GLONASS): GPS ids are the PRNs (``sat_name`` /
``sat_id`` convert to "E05"). Every record is on the GPS reference-week scale (the reader converts once:
BDT = GPST − 14 s, BDT week = GPS week − 1356; Galileo's GST = GPST; GLONASS epochs in UTC + leap
seconds); ``E_TOES`` keeps toe in the system's own seconds of week, which the node longitude needs
(Ω_k = Ω0 + (Ω̇ − ω_e) t_k − ω_e·toe_sow). Galileo and BeiDou are Keplerian like GPS with their own μ and
ω_e (Galileo OS SIS ICD: 3.986004418e14, 7.2921151467e-5; BeiDou ICD, CGCS2000: 3.986004418e14,
7.2921150e-5); BeiDou GEO satellites (PRN 1–5, 59–63) are computed in the inclined frame and rotated by
R_z(ω_e t_k)·R_x(−5°) (BeiDou ICD 5.2.4.12; velocity by central difference). GLONASS records hold the
PZ-90 state at t_b (``G_POS``, ``G_VEL``, the luni-solar acceleration ``G_ACC``, the frequency channel
``G_FCN``; clock −τ_n in ``E_AF0``, γ_n in ``E_AF1``) and are propagated by the ICD's 4th-order
Runge-Kutta (GLONASS ICD 5.1 A.3.1.2: central field + J2⁰ in the rotating frame, 60-s steps, the
acceleration held constant); PZ-90.11 is taken as WGS-84 (cm level). SBAS GEO satellites (S = 4, "S31" =
PRN 131) have the same state-vector records, propagated quadratically over ≤ 360 s (RTKLIB's seph2pos),
their clocks on GPS time (no inter-system bias; σ factor 3 as RTKLIB's EFACT_SBS).
"""

from __future__ import annotations

import numpy as np

from aidnav.jit import njit
from aidnav.units import DEG

from .earth import OMEGA_IE, ecef_to_lla

C_LIGHT = 299792458.0  #: speed of light [m/s]
GM_GPS = 3.986005e14  #: GPS value of the Earth's gravitational constant (IS-GPS-200) [m^3/s^2]
OMEGA_E_GPS = 7.2921151467e-5  #: Earth rotation rate of IS-GPS-200 [rad/s] (= OMEGA_IE)
F_REL = -4.442807633e-10  #: relativistic clock constant F = −2√μ/c² [s/√m]
FREQ_L1 = 1575.42e6  #: GPS L1 [Hz]
FREQ_L2 = 1227.60e6  #: GPS L2 [Hz]
LAMBDA_L1 = C_LIGHT / FREQ_L1  #: L1 wavelength [m]
PI_GPS = 3.1415926535898  #: π as IS-GPS-200 defines it (semicircles ↔ rad)
FREQ_B1I = 1561.098e6  #: BeiDou B1I [Hz]
FREQ_G1 = 1602.0e6  #: GLONASS G1 centre [Hz]; channel k: FREQ_G1 + k·DFREQ_G1
DFREQ_G1 = 0.5625e6  #: GLONASS G1 channel spacing [Hz]
GM_GAL = 3.986004418e14  #: Galileo OS SIS ICD [m^3/s^2]
GM_BDS = 3.986004418e14  #: BeiDou ICD (CGCS2000) [m^3/s^2]
OMEGA_E_BDS = 7.2921150e-5  #: BeiDou ICD (CGCS2000) [rad/s]
MU_GLO = 3.9860044e14  #: GLONASS ICD (PZ-90) [m^3/s^2]
J2_GLO = 1.0826257e-3  #: GLONASS ICD second zonal harmonic J2⁰ [-]
RE_GLO = 6378136.0  #: GLONASS ICD (PZ-90) equatorial radius [m]
OMEGA_E_GLO = 7.292115e-5  #: GLONASS ICD (PZ-90) [rad/s]
GLO_STEP_S = 60.0  #: Runge-Kutta step of the GLONASS orbit [s] (RTKLIB's TSTEP)
ERREPH_GLO = 5.0  #: URA given to GLONASS records (RINEX carries none) [m], RTKLIB's ERREPH_GLO
#: satellite systems of a satellite id (id // 100) and their RINEX letters
SYS_GPS, SYS_GAL, SYS_BDS, SYS_GLO, SYS_SBS = 0, 1, 2, 3, 4
SYSTEMS = "GECRS"
#: zenith code σ factor per system (RTKLIB's EFACT_GPS/GAL/CMP/GLO/SBS: 1, 1, 1, 1.5, 3)
SYSTEM_SIGMA_FACTOR = {"G": 1.0, "E": 1.0, "C": 1.0, "R": 1.5, "S": 3.0}
#: longest |t − toe| of a record per system [s] (RTKLIB's MAXDTOE*: GPS 7200, GAL 14400, BDS 21600,
#: GLONASS 1800, SBAS 360)
MAX_AGE_S = {"G": 7200.0, "E": 14400.0, "C": 21600.0, "R": 1800.0, "S": 360.0}
_SIN_5, _COS_5 = -0.0871557427476582, 0.9961946980917456  # sin/cos(−5°) of BeiDou GEO

# ephemeris record columns
E_PRN, E_WEEK, E_TOE, E_TOC, E_AF0, E_AF1, E_AF2 = 0, 1, 2, 3, 4, 5, 6
E_SQRTA, E_ECC, E_I0, E_OMEGA0, E_OMEGA, E_M0, E_DN, E_IDOT, E_OMEGADOT = 7, 8, 9, 10, 11, 12, 13, 14, 15
E_CUC, E_CUS, E_CRC, E_CRS, E_CIC, E_CIS = 16, 17, 18, 19, 20, 21
E_TGD, E_HEALTH, E_IODE, E_URA, E_FIT = 22, 23, 24, 25, 26
E_TOES = 27  # toe in the system's own seconds of week (for the node longitude; module doc)
N_EPH = 28
# GLONASS records: PZ-90 position [m], velocity [m/s], luni-solar acceleration [m/s²] at t_b (= E_TOE), the
# frequency channel k (E_AF0 = −τ_n [s], E_AF1 = γ_n [-], E_HEALTH, E_URA as for the others)
G_POS, G_VEL, G_ACC, G_FCN = 7, 10, 13, 16
EPH_COLUMNS = ("prn", "week", "toe", "toc", "af0", "af1", "af2", "sqrtA", "e", "i0", "Omega0", "omega",
    "M0", "deltaN", "IDOT", "OmegaDot", "Cuc", "Cus", "Crc", "Crs", "Cic", "Cis", "TGD", "health", "IODE",
    "URA", "fit_h", "toe_sow")
#: toe and toc in an ephemeris record are on the reference-week scale of the table (see module doc).


@njit(cache=True)
def eph_state(eph, t):
    """Satellite state from one ephemeris record ``eph`` (N_EPH,) at GPS time ``t`` [s] (GPS system time
    of transmission, reference-week scale), for every system (module doc).

    Returns (pos (3,) ECEF of time t [m], vel (3,) [m/s], dts [s] satellite clock offset incl. the
    relativistic term, ddts [s/s] its rate). IS-GPS-200 Table 20-IV; E_k by Newton iteration to 1e-14.
    """
    sys = int(eph[E_PRN]) // 100
    if sys == SYS_GLO:
        return glonass_state(eph, t)
    if sys == SYS_SBS:  # RTKLIB's seph2pos: position, velocity and acceleration at t0, quadratic
        tk = t - eph[E_TOE]
        a = eph[G_ACC:G_ACC + 3]
        pos = eph[G_POS:G_POS + 3] + eph[G_VEL:G_VEL + 3] * tk + 0.5 * a * tk * tk
        return pos, eph[G_VEL:G_VEL + 3] + a * tk, eph[E_AF0] + eph[E_AF1] * tk, eph[E_AF1]
    prn = int(eph[E_PRN]) % 100
    if sys == SYS_BDS and (prn <= 5 or prn >= 59):
        p1 = _kepler_pos(eph, t - 0.5, GM_BDS, OMEGA_E_BDS, True)[0]
        p2 = _kepler_pos(eph, t + 0.5, GM_BDS, OMEGA_E_BDS, True)[0]
        pos, ek, ek_dot = _kepler_pos(eph, t, GM_BDS, OMEGA_E_BDS, True)
        fr = -2.0 * np.sqrt(GM_BDS) / (C_LIGHT * C_LIGHT)
        dt = t - eph[E_TOC]
        dts = eph[E_AF0] + eph[E_AF1] * dt + eph[E_AF2] * dt * dt
        dts += fr * eph[E_ECC] * eph[E_SQRTA] * np.sin(ek)
        ddts = eph[E_AF1] + 2.0 * eph[E_AF2] * dt + fr * eph[E_ECC] * eph[E_SQRTA] * np.cos(ek) * ek_dot
        return pos, p2 - p1, dts, ddts
    gm, om_e, f_rel = _kepler_system(sys)
    x, y, z, vx, vy, vz, dts, ddts = _kepler_scalars(eph, t, gm, om_e, f_rel, np.nan)
    return np.array([x, y, z]), np.array([vx, vy, vz]), dts, ddts


@njit(cache=True)
def _kepler_system(sys):
    """(μ, ω_e, relativistic F) of a Keplerian system's records (GPS, Galileo, BeiDou MEO/IGSO)."""
    if sys == SYS_BDS:
        return GM_BDS, OMEGA_E_BDS, -2.0 * np.sqrt(GM_BDS) / (C_LIGHT * C_LIGHT)
    if sys == SYS_GAL:
        return GM_GAL, OMEGA_E_GPS, -2.0 * np.sqrt(GM_GAL) / (C_LIGHT * C_LIGHT)
    return GM_GPS, OMEGA_E_GPS, F_REL


@njit(cache=True)
def eph_clock(eph, t):
    """dts [s] of :func:`eph_state` (the same arithmetic, so the same bits) without the orbit: E_k alone
    for a Keplerian record (GPS, Galileo, BeiDou MEO/IGSO), GLONASS and SBAS clocks as they are (no
    propagation); BeiDou GEO through :func:`eph_state`.
    The transmit-time passes of :func:`sat_from_pseudorange` need only the clock."""
    sys, prn = int(eph[E_PRN]) // 100, int(eph[E_PRN]) % 100
    if sys == SYS_GLO or sys == SYS_SBS:  # eph_state's clock of these records (no orbit propagated)
        return eph[E_AF0] + eph[E_AF1] * (t - eph[E_TOE])
    if sys == SYS_BDS and (prn <= 5 or prn >= 59):
        return eph_state(eph, t)[2]
    gm, _, f_rel = _kepler_system(sys)
    a = eph[E_SQRTA] ** 2  # as _kepler_scalars
    ecc = eph[E_ECC]
    n0 = np.sqrt(gm / (a * a * a))
    tk = t - eph[E_TOE]
    n = n0 + eph[E_DN]
    mk = eph[E_M0] + n * tk
    se = np.sin(eccentric_anomaly(mk, ecc))
    dt = t - eph[E_TOC]
    return eph[E_AF0] + eph[E_AF1] * dt + eph[E_AF2] * dt * dt + f_rel * ecc * eph[E_SQRTA] * se


@njit(cache=True)
def eccentric_anomaly(mk, ecc):
    """Kepler's equation E − e sin E = M solved for the eccentric anomaly E [rad] by Newton's iteration from
    E = M (at most 30 steps, until a step is below 1e-14 rad), for mean anomaly ``mk`` [rad] and
    eccentricity ``ecc`` (0 ≤ e < 1): the one solver of every Keplerian record (GPS, Galileo, BeiDou)."""
    return eccentric_anomaly_from(mk, ecc, mk)


@njit(cache=True)
def eccentric_anomaly_from(mk, ecc, ek):
    """:func:`eccentric_anomaly` by Newton's iteration from ``ek`` (a warm start; from ``mk`` the same)."""
    for _ in range(30):
        d = (ek - ecc * np.sin(ek) - mk) / (1.0 - ecc * np.cos(ek))
        ek -= d
        if abs(d) < 1e-14:
            break
    return ek


@njit(cache=True)
def _kepler_pos(eph, t, gm, om_e, geo):
    """Position of a Keplerian record (BeiDou GEO when ``geo``: BeiDou ICD 5.2.4.12), E_k and its rate."""
    a = eph[E_SQRTA] ** 2
    ecc = eph[E_ECC]
    tk = t - eph[E_TOE]
    n = np.sqrt(gm / (a * a * a)) + eph[E_DN]
    mk = eph[E_M0] + n * tk
    ek = eccentric_anomaly(mk, ecc)
    se, ce = np.sin(ek), np.cos(ek)
    vk = np.arctan2(np.sqrt(1.0 - ecc * ecc) * se, ce - ecc)
    phi = vk + eph[E_OMEGA]
    s2, c2 = np.sin(2.0 * phi), np.cos(2.0 * phi)
    u = phi + eph[E_CUS] * s2 + eph[E_CUC] * c2
    r = a * (1.0 - ecc * ce) + eph[E_CRS] * s2 + eph[E_CRC] * c2
    inc = eph[E_I0] + eph[E_CIS] * s2 + eph[E_CIC] * c2 + eph[E_IDOT] * tk
    xp, yp = r * np.cos(u), r * np.sin(u)
    if geo:
        om = eph[E_OMEGA0] + eph[E_OMEGADOT] * tk - om_e * eph[E_TOES]
    else:
        om = eph[E_OMEGA0] + (eph[E_OMEGADOT] - om_e) * tk - om_e * eph[E_TOES]
    so, co, si, ci = np.sin(om), np.cos(om), np.sin(inc), np.cos(inc)
    x, y, z = xp * co - yp * ci * so, xp * so + yp * ci * co, yp * si
    pos = np.empty(3)
    if geo:
        sn, cn = np.sin(om_e * tk), np.cos(om_e * tk)
        pos[0] = x * cn + y * sn * _COS_5 + z * sn * _SIN_5
        pos[1] = -x * sn + y * cn * _COS_5 + z * cn * _SIN_5
        pos[2] = -y * _SIN_5 + z * _COS_5
    else:
        pos[0], pos[1], pos[2] = x, y, z
    return pos, ek, n / (1.0 - ecc * ce)


@njit(cache=True)
def _glo_deriv(x, acc):
    """Time derivative of the GLONASS state (position, velocity) in the rotating PZ-90 frame (ICD A.3.1.2)."""
    r2 = x[0] * x[0] + x[1] * x[1] + x[2] * x[2]
    r3 = r2 * np.sqrt(r2)
    om2 = OMEGA_E_GLO * OMEGA_E_GLO
    a = 1.5 * J2_GLO * MU_GLO * RE_GLO * RE_GLO / r2 / r3
    b = 5.0 * x[2] * x[2] / r2
    c = -MU_GLO / r3 - a * (1.0 - b)
    xd = np.empty(6)
    xd[0], xd[1], xd[2] = x[3], x[4], x[5]
    xd[3] = (c + om2) * x[0] + 2.0 * OMEGA_E_GLO * x[4] + acc[0]
    xd[4] = (c + om2) * x[1] - 2.0 * OMEGA_E_GLO * x[3] + acc[1]
    xd[5] = (c - 2.0 * a) * x[2] + acc[2]
    return xd


@njit(cache=True)
def glonass_orbit(x0, acc, tk, step):
    """PZ-90 state (6,) after ``tk`` [s] from ``x0`` (position, velocity) by 4th-order Runge-Kutta steps
    of at most ``step`` [s] (the last one shorter), the luni-solar acceleration ``acc`` held constant."""
    x = x0.copy()
    tt = tk
    while abs(tt) > 1e-9:
        h = step if tt > 0 else -step
        if abs(tt) < step:
            h = tt
        k1 = _glo_deriv(x, acc)
        k2 = _glo_deriv(x + 0.5 * h * k1, acc)
        k3 = _glo_deriv(x + 0.5 * h * k2, acc)
        k4 = _glo_deriv(x + h * k3, acc)
        x = x + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        tt -= h
    return x


@njit(cache=True)
def glonass_state(eph, t):
    """GLONASS satellite state at GPS time ``t`` from a record (module doc): (pos, vel, dts, ddts) with
    dts = −τ_n + γ_n (t − t_b)."""
    tk = t - eph[E_TOE]
    x0 = np.empty(6)
    x0[:3] = eph[G_POS:G_POS + 3]
    x0[3:] = eph[G_VEL:G_VEL + 3]
    x = glonass_orbit(x0, eph[G_ACC:G_ACC + 3].copy(), tk, GLO_STEP_S)
    return x[:3].copy(), x[3:].copy(), eph[E_AF0] + eph[E_AF1] * tk, eph[E_AF1]


@njit(cache=True)
def _kepler_scalars(eph, t, gm, om_e, f_rel, ek):
    """Keplerian record (GPS, Galileo, BeiDou MEO/IGSO) with the system's μ, ω_e and relativistic F: (x, y,
    z, vx, vy, vz, dts, ddts) as scalars, no arrays (issue 40, session 17: ~2,000 satellites a tight call);
    ``ek`` E_k at ``t`` where known (NaN: solved here)."""
    a = eph[E_SQRTA] ** 2
    ecc = eph[E_ECC]
    n0 = np.sqrt(gm / (a * a * a))
    tk = t - eph[E_TOE]
    n = n0 + eph[E_DN]
    if np.isnan(ek):
        ek = eccentric_anomaly(eph[E_M0] + n * tk, ecc)
    se, ce = np.sin(ek), np.cos(ek)
    den = 1.0 - ecc * ce
    sq = np.sqrt(1.0 - ecc * ecc)
    vk = np.arctan2(sq * se, ce - ecc)
    phi = vk + eph[E_OMEGA]
    s2, c2 = np.sin(2.0 * phi), np.cos(2.0 * phi)
    du = eph[E_CUS] * s2 + eph[E_CUC] * c2
    dr = eph[E_CRS] * s2 + eph[E_CRC] * c2
    di = eph[E_CIS] * s2 + eph[E_CIC] * c2
    u = phi + du
    r = a * den + dr
    inc = eph[E_I0] + di + eph[E_IDOT] * tk
    xp, yp = r * np.cos(u), r * np.sin(u)
    omk_dot = eph[E_OMEGADOT] - om_e
    om = eph[E_OMEGA0] + omk_dot * tk - om_e * eph[E_TOES]
    so, co = np.sin(om), np.cos(om)
    si, ci = np.sin(inc), np.cos(inc)
    x = xp * co - yp * ci * so
    y = xp * so + yp * ci * co
    z = yp * si
    # derivatives
    ek_dot = n / den
    vk_dot = ek_dot * sq / den
    u_dot = vk_dot * (1.0 + 2.0 * (eph[E_CUS] * c2 - eph[E_CUC] * s2))
    r_dot = a * ecc * se * ek_dot + 2.0 * vk_dot * (eph[E_CRS] * c2 - eph[E_CRC] * s2)
    i_dot = eph[E_IDOT] + 2.0 * vk_dot * (eph[E_CIS] * c2 - eph[E_CIC] * s2)
    xp_dot = r_dot * np.cos(u) - r * u_dot * np.sin(u)
    yp_dot = r_dot * np.sin(u) + r * u_dot * np.cos(u)
    vx = xp_dot * co - yp_dot * ci * so + yp * si * so * i_dot - y * omk_dot
    vy = xp_dot * so + yp_dot * ci * co - yp * si * co * i_dot + x * omk_dot
    vz = yp_dot * si + yp * ci * i_dot
    dt = t - eph[E_TOC]
    dts = eph[E_AF0] + eph[E_AF1] * dt + eph[E_AF2] * dt * dt + f_rel * ecc * eph[E_SQRTA] * se
    ddts = eph[E_AF1] + 2.0 * eph[E_AF2] * dt + f_rel * ecc * eph[E_SQRTA] * ce * ek_dot
    return x, y, z, vx, vy, vz, dts, ddts


@njit(cache=True)
def sat_from_pseudorange(eph, t_rx, pr, use_tgd):
    """Satellite state at the transmit time implied by a pseudorange.

    t_rx : receiver time tag [s] (reference-week scale; includes the receiver clock offset);
    pr : pseudorange [m]. Transmit time in satellite time t_sv = t_rx − pr/c, in GPS time
    t = t_sv − dt_s(t) (two fixed-point passes). ``use_tgd``: subtract T_GD from dt_s (L1 C/A user).
    Returns (pos, vel (ECEF of transmit time), dts [s], ddts [s/s]).
    """
    t_sv = t_rx - pr / C_LIGHT
    t = t_sv
    for _ in range(2):
        t = t_sv - eph_clock(eph, t)
    pos, vel, dts, ddts = eph_state(eph, t)
    if use_tgd:
        dts -= eph[E_TGD]
    return pos, vel, dts, ddts


@njit(cache=True)
def sat_from_pseudorange_scalars(eph, t_rx, pr, use_tgd):
    """:func:`sat_from_pseudorange`'s values (the same arithmetic: the same bits) as scalars (x, y, z, vx,
    vy, vz, dts, ddts), no arrays for a Keplerian record (the others through :func:`eph_state`)."""
    t_sv = t_rx - pr / C_LIGHT
    t = t_sv
    for _ in range(2):
        t = t_sv - eph_clock(eph, t)
    sys, prn = int(eph[E_PRN]) // 100, int(eph[E_PRN]) % 100
    if sys == SYS_GLO or sys == SYS_SBS or (sys == SYS_BDS and (prn <= 5 or prn >= 59)):
        p, v, dts, ddts = eph_state(eph, t)
        x, y, z, vx, vy, vz = p[0], p[1], p[2], v[0], v[1], v[2]
    else:
        gm, om_e, f_rel = _kepler_system(sys)
        x, y, z, vx, vy, vz, dts, ddts = _kepler_scalars(eph, t, gm, om_e, f_rel, np.nan)
    if use_tgd:
        dts -= eph[E_TGD]
    return x, y, z, vx, vy, vz, dts, ddts


@njit(cache=True)
def sat_from_pseudorange_once(eph, t_rx, pr, use_tgd, warm):
    """:func:`sat_from_pseudorange_scalars`' values with one Kepler solve for a Keplerian record (the others
    through it): E_k at t_sv = t_rx − pr/c by Newton's iteration from ``warm`` = (E, M, 1 − e cos E) of an
    earlier solve of this record within 0.1 rad of M, which become this one's (NaN: from M); the two
    fixed-point passes t = t_sv − dt_s(t) to first order in dt_s's rate and E_k at t by its rate (second
    orders ~1e-22 s and ~1e-19 rad, below the round-off: results differ from the passes' by a few ulps of
    E_k, ~1e-8 m). Issue 40, session 18: three Newton solves a satellite were ~40 % of the tight call's
    satellite states."""
    sys, prn = int(eph[E_PRN]) // 100, int(eph[E_PRN]) % 100
    if sys == SYS_GLO or sys == SYS_SBS or (sys == SYS_BDS and (prn <= 5 or prn >= 59)):
        warm[0] = np.nan
        return sat_from_pseudorange_scalars(eph, t_rx, pr, use_tgd)
    gm, om_e, f_rel = _kepler_system(sys)
    t_sv = t_rx - pr / C_LIGHT
    a, ecc = eph[E_SQRTA] ** 2, eph[E_ECC]
    n = np.sqrt(gm / (a * a * a)) + eph[E_DN]
    mk = eph[E_M0] + n * (t_sv - eph[E_TOE])
    dm = mk - warm[1]
    ek = eccentric_anomaly_from(mk, ecc, warm[0] + dm / warm[2] if abs(dm) < 0.1 else mk)
    se, ce = np.sin(ek), np.cos(ek)
    dt = t_sv - eph[E_TOC]
    warm[0], warm[1], warm[2] = ek, mk, 1.0 - ecc * ce
    dts = eph[E_AF0] + eph[E_AF1] * dt + eph[E_AF2] * dt * dt + f_rel * ecc * eph[E_SQRTA] * se
    ddts = eph[E_AF1] + 2.0 * eph[E_AF2] * dt + f_rel * ecc * eph[E_SQRTA] * ce * n / warm[2]
    t = t_sv - (dts - ddts * dts)  # t_sv − dt_s(t_sv − dt_s(t_sv)) to first order
    x, y, z, vx, vy, vz, dts, ddts = _kepler_scalars(eph, t, gm, om_e, f_rel, ek + n / warm[2] * (t - t_sv))
    if use_tgd:
        dts -= eph[E_TGD]
    return x, y, z, vx, vy, vz, dts, ddts


@njit(cache=True)
def geo_range(rs, rr):
    """Range [m] with the first-order Sagnac correction and the unit vector e^e receiver → satellite.

    rs : satellite position at transmit time (ECEF of that time), rr : receiver ECEF at receive time.
    """
    d0, d1, d2 = rs[0] - rr[0], rs[1] - rr[1], rs[2] - rr[2]
    r = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
    e = np.empty(3)
    e[0], e[1], e[2] = d0 / r, d1 / r, d2 / r
    return r + OMEGA_E_GPS * (rs[0] * rr[1] - rs[1] * rr[0]) / C_LIGHT, e


@njit(cache=True)
def geo_range_rate(rs, vs, rr, vr, e):
    """Range rate [m/s] e·(v_s − v_r) with the first-order Sagnac rate term (see module doc)."""
    rate = e[0] * (vs[0] - vr[0]) + e[1] * (vs[1] - vr[1]) + e[2] * (vs[2] - vr[2])
    return rate + OMEGA_E_GPS / C_LIGHT * (vs[1] * rr[0] + rs[1] * vr[0] - vs[0] * rr[1] - rs[0] * vr[1])


@njit(cache=True)
def az_el(e_ecef, lat, lon):
    """Azimuth (clockwise from North, [0, 2π)) and elevation [rad] of the ECEF unit vector ``e_ecef``
    seen from (lat, lon) [rad]; also returns the ENU unit vector (3,)."""
    sl, cl, so, co = np.sin(lat), np.cos(lat), np.sin(lon), np.cos(lon)
    enu = np.empty(3)
    enu[0] = -so * e_ecef[0] + co * e_ecef[1]
    enu[1] = -sl * co * e_ecef[0] - sl * so * e_ecef[1] + cl * e_ecef[2]
    enu[2] = cl * co * e_ecef[0] + cl * so * e_ecef[1] + sl * e_ecef[2]
    az = np.arctan2(enu[0], enu[1])
    if az < 0.0:
        az += 2.0 * np.pi
    el = np.arcsin(min(1.0, max(-1.0, enu[2])))
    return az, el, enu


@njit(cache=True)
def klobuchar(lat, lon, az, el, t_sow, alpha, beta):
    """GPS broadcast (Klobuchar) ionospheric L1 group delay [m] (IS-GPS-200 20.3.3.5.2.5).

    lat, lon : user geodetic [rad]; az, el : satellite azimuth/elevation [rad]; t_sow : GPS seconds
    (any week scale: only t mod 86400 enters); alpha, beta (4,) broadcast coefficients [s, s/sc, ...].
    Night-time floor 5 ns; obliquity F = 1 + 16 (0.53 − E)³ with E in semicircles. For L2 multiply by
    (f1/f2)².
    """
    e_sc = el / PI_GPS
    psi = 0.0137 / (e_sc + 0.11) - 0.022
    phi_i = lat / PI_GPS + psi * np.cos(az)
    if phi_i > 0.416:
        phi_i = 0.416
    elif phi_i < -0.416:
        phi_i = -0.416
    lam_i = lon / PI_GPS + psi * np.sin(az) / np.cos(phi_i * PI_GPS)
    phi_m = phi_i + 0.064 * np.cos((lam_i - 1.617) * PI_GPS)
    t = 4.32e4 * lam_i + t_sow
    t = t - np.floor(t / 86400.0) * 86400.0
    f = 1.0 + 16.0 * (0.53 - e_sc) ** 3
    amp = alpha[0] + phi_m * (alpha[1] + phi_m * (alpha[2] + phi_m * alpha[3]))
    per = beta[0] + phi_m * (beta[1] + phi_m * (beta[2] + phi_m * beta[3]))
    if amp < 0.0:
        amp = 0.0
    if per < 72000.0:
        per = 72000.0
    x = 2.0 * np.pi * (t - 50400.0) / per
    if abs(x) < 1.57:
        delay = f * (5e-9 + amp * (1.0 - x * x / 2.0 + x**4 / 24.0))
    else:
        delay = f * 5e-9
    return C_LIGHT * delay


@njit(cache=True)
def std_atmosphere(h, rel_humidity):
    """Standard atmosphere at height h [m] (clamped at ≥ 0): pressure [hPa], temperature [K], water-vapour
    partial pressure [hPa] (Magnus-type formula used by RTKLIB's Saastamoinen model)."""
    hg = max(h, 0.0)
    p = 1013.25 * (1.0 - 2.2557e-5 * hg) ** 5.2568
    tk = 15.0 - 6.5e-3 * hg + 273.15
    e = 6.108 * rel_humidity * np.exp((17.15 * tk - 4684.0) / (tk - 38.45))
    return p, tk, e


@njit(cache=True)
def saastamoinen_zenith(lat, h, p_hpa, t_k, e_hpa):
    """Saastamoinen zenith hydrostatic and wet delays [m] from pressure [hPa], temperature [K] and
    water-vapour pressure [hPa] at (lat [rad], h [m]):
    ZHD = 0.0022768 P / (1 − 0.00266 cos 2φ − 0.00028 h[km]); ZWD = 0.002277 (1255/T + 0.05) e."""
    zhd = 0.0022768 * p_hpa / (1.0 - 0.00266 * np.cos(2.0 * lat) - 0.00028 * max(h, 0.0) * 1e-3)
    zwd = 0.002277 * (1255.0 / t_k + 0.05) * e_hpa
    return zhd, zwd


@njit(cache=True)
def trop_mapping(el):
    """Tropospheric mapping function of Black & Eisner (1984), m(E) = 1.001/√(0.002001 + sin²E), as in
    RTCA DO-229 (valid above ~3°; elevations below 2° are clamped to 2°)."""
    s = np.sin(max(el, 2.0 * DEG))
    return 1.001 / np.sqrt(0.002001 + s * s)


@njit(cache=True)
def tropo_delay(lat, h, el, rel_humidity):
    """Slant tropospheric delay [m]: Saastamoinen zenith delays in the standard atmosphere at the receiver
    height (relative humidity ``rel_humidity`` in [0, 1]) times :func:`trop_mapping`. 0 for h outside
    [−100 m, 20 km] (above most of the atmosphere the model does not hold; aircraft stay below)."""
    if h < -100.0 or h > 2.0e4 or el <= 0.0:
        return 0.0
    p, tk, e = std_atmosphere(h, rel_humidity)
    zhd, zwd = saastamoinen_zenith(lat, h, p, tk, e)
    return (zhd + zwd) * trop_mapping(el)


@njit(cache=True)
def select_ephemeris(eph_table, prn, t, max_age):
    """Index of the healthy record of satellite ``prn`` (id: module doc) whose toe is closest to ``t`` with
    |t − toe| ≤ max_age [s] (GLONASS: at most 1800 s, the RK4 propagation's span; SBAS 360 s); −1 if
    none."""
    best = -1
    best_d = min(max_age, 1800.0) if prn // 100 == SYS_GLO else max_age
    if prn // 100 == SYS_SBS:
        best_d = min(max_age, 360.0)
    for i in range(eph_table.shape[0]):
        if int(eph_table[i, E_PRN]) != prn or eph_table[i, E_HEALTH] != 0.0:
            continue
        d = abs(t - eph_table[i, E_TOE])
        if d <= best_d:
            best_d = d
            best = i
    return best


@njit(cache=True)
def sat_states(eph_table, eph_idx, t):
    """Positions (S, 3), velocities (S, 3), clocks dts (S,) [s] and rates (S,) of the records
    ``eph_idx`` (S,) at GPS time ``t`` (no transmit-time iteration: for geometry and visibility)."""
    s = eph_idx.shape[0]
    pos = np.full((s, 3), np.nan)
    vel = np.full((s, 3), np.nan)
    dts = np.full(s, np.nan)
    ddts = np.full(s, np.nan)
    for j in range(s):
        if eph_idx[j] < 0:
            continue
        p, v, c, cd = eph_state(eph_table[eph_idx[j]], t)
        pos[j] = p
        vel[j] = v
        dts[j] = c
        ddts[j] = cd
    return pos, vel, dts, ddts


def dop(enu_unit, weights=None) -> dict:
    """Dilution of precision from ENU unit vectors receiver → satellite (n, 3) (n ≥ 4; rows [−e, 1]).

    Returns {gdop, pdop, hdop, vdop, tdop, edop, ndop}; inf where the geometry is singular. With
    ``weights`` (n,) the weighted form (HᵀWH)⁻¹ is used.
    """
    u = np.asarray(enu_unit, float).reshape(-1, 3)
    h = np.column_stack([-u, np.ones(len(u))])
    w = np.ones(len(u)) if weights is None else np.asarray(weights, float)
    inf = {k: float("inf") for k in ("gdop", "pdop", "hdop", "vdop", "tdop", "edop", "ndop")}
    if len(u) < 4:
        return inf
    n = h.T @ (h * w[:, None])
    if np.linalg.cond(n) > 1e12:
        return inf
    q = np.linalg.inv(n)
    d = np.diag(q)
    return {
        "gdop": float(np.sqrt(d.sum())),
        "pdop": float(np.sqrt(d[:3].sum())),
        "hdop": float(np.sqrt(d[:2].sum())),
        "vdop": float(np.sqrt(d[2])),
        "tdop": float(np.sqrt(d[3])),
        "edop": float(np.sqrt(d[0])),
        "ndop": float(np.sqrt(d[1])),
    }


def visible(sat_pos, rx_ecef, mask_deg: float = 5.0):
    """Elevation mask test: (visible (S,) bool, azimuth (S,) [rad], elevation (S,) [rad]) of satellites
    at ECEF ``sat_pos`` (S, 3) seen from the receiver ``rx_ecef`` (3,)."""
    sp = np.asarray(sat_pos, float).reshape(-1, 3)
    rr = np.asarray(rx_ecef, float)
    lat, lon, _ = ecef_to_lla(rr[0], rr[1], rr[2])
    az = np.full(len(sp), np.nan)
    el = np.full(len(sp), np.nan)
    for j in range(len(sp)):
        if not np.all(np.isfinite(sp[j])):
            continue
        _, e = geo_range(sp[j], rr)
        az[j], el[j], _ = az_el(e, lat, lon)
    vis = np.isfinite(el) & (el >= np.radians(mask_deg))
    return vis, az, el


def dual_frequency_iono(time, code1, code2, window_s: float) -> np.ndarray:
    """L1 ionospheric delay [m] per epoch and satellite from the geometry-free code combination
    I₁ = (P₂ − P₁)/(γ − 1), γ = (f₁/f₂)², averaged over a centred window of ``window_s`` seconds per
    satellite (the combination's noise is ≈ 2.3× the code noise; the ionosphere changes little over a
    minute). time (T,) [s]; code1, code2 (T, S) pseudoranges [m], NaN where missing → (T, S), NaN where
    no L1/L2 pair."""
    gam = (FREQ_L1 / FREQ_L2) ** 2
    i1 = (code2 - code1) / (gam - 1.0)
    out = np.full_like(i1, np.nan)
    half = window_s / 2
    for j in range(i1.shape[1]):
        ok = np.isfinite(i1[:, j])
        tj, ij = time[ok], i1[ok, j]
        if not len(tj):
            continue
        cs = np.concatenate([[0.0], np.cumsum(ij)])
        lo = np.searchsorted(tj, tj - half, "left")
        hi = np.searchsorted(tj, tj + half, "right")
        out[np.flatnonzero(ok), j] = (cs[hi] - cs[lo]) / (hi - lo)
    return out


__all__ = ["dual_frequency_iono", "C_LIGHT", "GM_GPS", "OMEGA_E_GPS", "F_REL", "FREQ_L1", "FREQ_L2",
           "LAMBDA_L1", "N_EPH", "EPH_COLUMNS", "eph_state", "eph_clock", "sat_from_pseudorange",
           "sat_from_pseudorange_scalars", "sat_from_pseudorange_once", "geo_range", "geo_range_rate",
           "az_el", "klobuchar", "klobuchar_coefficients", "KLOBUCHAR_DEFAULT_ALPHA",
           "KLOBUCHAR_DEFAULT_BETA", "iono_fallback_note", "std_atmosphere", "saastamoinen_zenith",
           "trop_mapping", "tropo_delay", "select_ephemeris", "sat_states", "dop", "visible", "OMEGA_IE",
           "range_error_sigma", "ERR_BRDCI", "ERR_ION", "ERR_SAAS", "ERR_TROP", "ERR_CBIAS"]


# ------------------------------------------------------- satellites of an epoch, measurement weights
@njit(cache=True)
def elevation_sigma(sigma0, el):
    """σ(E) = σ0 √(½ + ½/sin²E) [m] (E clamped at 2°)."""
    s = np.sin(max(el, 0.035))
    return sigma0 * np.sqrt(0.5 + 0.5 / (s * s))


@njit(cache=True)
def satellite_states(eph_table, prns, t_rx, pr, use_tgd, max_age):
    """numba core of :func:`satellites_from_pseudoranges` (arrays already typed)."""
    s = prns.shape[0]
    pos = np.full((s, 3), np.nan)
    vel = np.full((s, 3), np.nan)
    clk = np.full(s, np.nan)
    clk_rate = np.full(s, np.nan)
    for j in range(s):
        if not np.isfinite(pr[j]):
            continue
        i = select_ephemeris(eph_table, prns[j], t_rx, max_age)
        if i < 0:
            continue
        p, v, dts, ddts = sat_from_pseudorange(eph_table[i], t_rx, pr[j], use_tgd)
        pos[j] = p
        vel[j] = v
        clk[j] = dts * C_LIGHT
        clk_rate[j] = ddts * C_LIGHT
    return pos, vel, clk, clk_rate


@njit(cache=True)
def satellite_states_epochs(eph_table, prns, t_rx, pr, use_tgd, max_age):
    """:func:`satellite_states` of every epoch in one call (M epochs, S satellites: t_rx (M,), pr (M, S)),
    and the URA [m] of the ephemeris record used (NaN where none). Returns pos (M, S, 3), vel (M, S, 3),
    clk (M, S), clk_rate (M, S), ura (M, S)."""
    m, s = pr.shape
    pos, vel = np.full((m, s, 3), np.nan), np.full((m, s, 3), np.nan)
    clk, clk_rate, ura = np.full((m, s), np.nan), np.full((m, s), np.nan), np.full((m, s), np.nan)
    for k in range(m):  # satellite_states' loop, written into the epoch's rows (no per-epoch arrays)
        for j in range(s):
            if not np.isfinite(pr[k, j]):
                continue
            i = select_ephemeris(eph_table, prns[j], t_rx[k], max_age)
            if i < 0:
                continue
            p, v, dts, ddts = sat_from_pseudorange(eph_table[i], t_rx[k], pr[k, j], use_tgd)
            pos[k, j], vel[k, j] = p, v
            clk[k, j], clk_rate[k, j] = dts * C_LIGHT, ddts * C_LIGHT
            ura[k, j] = eph_table[i, E_URA]
    return pos, vel, clk, clk_rate, ura


def satellites_from_pseudoranges(eph_table, prns, t_rx, pr, use_tgd: bool = True, max_age_s: float = 7200.0):
    """Satellite states at the transmit times implied by the pseudoranges of one epoch.

    eph_table : (K, N_EPH) ephemeris records (reference-week scale); prns (S,); t_rx receiver tag [s];
    pr (S,) [m] (NaN = no measurement). Returns (pos (S, 3) ECEF of transmit time [m], vel (S, 3) [m/s],
    clk (S,) c·dt_s [m], clk_rate (S,) c·ḋt_s [m/s]); NaN where no measurement or no ephemeris.
    """
    return satellite_states(
        np.ascontiguousarray(eph_table, float),
        np.asarray(prns, np.int64),
        float(t_rx),
        np.asarray(pr, float),
        bool(use_tgd),
        float(max_age_s),
    )


# ------------------------------------------- Klobuchar coefficients when the navigation file has none
#: RTKLIB's fallback Klobuchar coefficients (``rtkcmn.c``, ``ionmodel``: ``ion_default[]``, commented
#: "2004/1/1"; used when ``norm(ion, 8) <= 0``, i.e. no coefficients were broadcast/read), α [s, s/sc,
#: s/sc², s/sc³] and β [s, s/sc, s/sc², s/sc³]. RTKLIB's σ of the broadcast-model correction is
#: ERR_BRDCI (50 %) of the applied delay (``pntpos.c``, ``ionocorr``); aidnav states the same σ.
KLOBUCHAR_DEFAULT_ALPHA = np.array([0.1118e-07, -0.7451e-08, -0.5961e-07, 0.1192e-06])
KLOBUCHAR_DEFAULT_BETA = np.array([0.1167e06, -0.2294e06, -0.1311e06, 0.1049e07])


def klobuchar_coefficients(alpha, beta):
    """(α, β, source) for the Klobuchar model: the given coefficients ("broadcast") or, when there are none
    (None, or all zero as RTKLIB tests), RTKLIB's defaults ("default"; :data:`KLOBUCHAR_DEFAULT_ALPHA`)."""
    if alpha is None or beta is None or (np.all(np.asarray(alpha) == 0) and np.all(np.asarray(beta) == 0)):
        return KLOBUCHAR_DEFAULT_ALPHA.copy(), KLOBUCHAR_DEFAULT_BETA.copy(), "default"
    return np.asarray(alpha, float), np.asarray(beta, float), "broadcast"


def iono_fallback_note() -> str:
    """The one-line statement of the fallback for summaries and the console."""
    return ("no Klobuchar coefficients in the navigation file: RTKLIB's default coefficients "
            f"(rtkcmn.c ion_default, 2004/1/1) applied, sigma {100 * ERR_BRDCI:.0f} % of the delay")


# ------------------------------------------- single-frequency range-error budget (RTKLIB pntpos.c)
ERR_BRDCI = 0.5  #: broadcast (Klobuchar) ionosphere residual, fraction of the delay [-]
ERR_ION = 5.0  #: ionospheric delay σ with no ionospheric model [m]
ERR_SAAS = 0.3  #: Saastamoinen model residual σ at zenith [m]
ERR_TROP = 3.0  #: tropospheric delay σ with no tropospheric model [m]
ERR_CBIAS = 0.3  #: code bias σ [m]


@njit(cache=True)
def range_error_sigma(el, ura, iono_mode, iono_delay, tropo):
    """σ [m] of the time-correlated part of one L1 pseudorange error, RTKLIB's single-point budget
    (``pntpos.c``: ``ERR_*`` constants above, ``var_uraeph``, ``ionocorr``, ``tropcorr``):
    σ² = URA² + σ_ion² + σ_trop² + ERR_CBIAS², with σ_ion = ERR_BRDCI·I_Klobuchar (``iono_mode`` 1),
    ERR_ION (0: no ionospheric model) or 0 (2: dual-frequency delay removed); σ_trop =
    ERR_SAAS/(sin E + 0.1) with the Saastamoinen model (``tropo``), ERR_TROP/(sin E + 0.1) without.
    ura : the ephemeris' user range accuracy [m] (NaN or ≤ 0: 6144 m, RTKLIB's unknown-accuracy value);
    el [rad]; iono_delay [m] (the Klobuchar delay applied)."""
    u = ura if ura > 0.0 else 6144.0
    if iono_mode == 1:
        si = ERR_BRDCI * iono_delay
    elif iono_mode == 0:
        si = ERR_ION
    else:
        si = 0.0
    st = (ERR_SAAS if tropo else ERR_TROP) / (np.sin(max(el, 0.0)) + 0.1)
    return np.sqrt(u * u + si * si + st * st + ERR_CBIAS * ERR_CBIAS)


# ------------------------------------------------------------------ satellite ids of every constellation
def sat_id(name: str) -> int:
    """Satellite id (module doc) of a RINEX name such as "G05", "E11", "C30", "R07", "S31" (others:
    ValueError)."""
    name = str(name).strip()
    if name[:1] not in SYSTEMS or not name[1:].strip().isdigit():
        raise ValueError(f"satellite {name!r}: not a GPS, Galileo, BeiDou, GLONASS or SBAS name")
    return 100 * SYSTEMS.index(name[0]) + int(name[1:])


def sat_name(sid) -> str:
    """RINEX name ("G05") of a satellite id."""
    sid = int(sid)
    return f"{SYSTEMS[sid // 100]}{sid % 100:02d}"


def sat_system(ids) -> np.ndarray:
    """System letter per satellite id (array of one-character strings)."""
    return np.array([SYSTEMS[int(i) // 100] for i in np.atleast_1d(ids)])


def glonass_channels(eph_table) -> dict:
    """{satellite id: frequency channel k} of the GLONASS records of an ephemeris table."""
    t = np.asarray(eph_table)
    glo = t[(t[:, E_PRN] // 100).astype(int) == SYS_GLO]
    return {int(r[E_PRN]): int(r[G_FCN]) for r in glo}


def carrier_frequencies(ids, eph_table=None) -> np.ndarray:
    """Frequency [Hz] (S,) of the signal aidnav uses per satellite: GPS L1 C/A and Galileo E1 1575.42 MHz,
    BeiDou B1I 1561.098 MHz, GLONASS G1 1602 + 0.5625·k MHz with the channel k of the satellite's record in
    ``eph_table`` (NaN without one)."""
    ids = np.atleast_1d(np.asarray(ids, int))
    ch = glonass_channels(eph_table) if eph_table is not None else {}
    out = np.full(len(ids), FREQ_L1)
    for j, i in enumerate(ids):
        s = i // 100
        if s == SYS_BDS:
            out[j] = FREQ_B1I
        elif s == SYS_GLO:
            out[j] = FREQ_G1 + DFREQ_G1 * ch[int(i)] if int(i) in ch else np.nan
    return out


__all__ += ["sat_id", "sat_name", "sat_system", "glonass_channels", "carrier_frequencies", "glonass_state",
            "eccentric_anomaly", "eccentric_anomaly_from",
            "glonass_orbit", "SYSTEMS", "SYS_GPS", "SYS_GAL", "SYS_BDS", "SYS_GLO", "SYS_SBS",
            "SYSTEM_SIGMA_FACTOR",
            "MAX_AGE_S", "FREQ_B1I", "FREQ_G1", "DFREQ_G1", "E_TOES", "G_POS", "G_VEL", "G_ACC", "G_FCN"]
