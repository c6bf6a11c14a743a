"""Checks of the standard deviations and velocities that GNSS readers take from a file (one place for all).

Rules (issue 25, "partial and optional GNSS content"), applied by every GNSS reader of :mod:`aidnav.io`:

* velocity per component: NaN means "not measured" (kept as NaN; the filter uses only the measured
  components); ±inf is refused.
* σ columns are optional. Absent altogether → ``std_pos`` / ``std_vel`` stay None and an event names the
  σ the filter then uses (``gnss.default_pos_std_m`` / ``gnss.default_vel_std_m_s`` of the filter
  configuration, defaults :data:`DEFAULT_POS_STD_M`, :data:`DEFAULT_VEL_STD_M_S`). A σ that is NaN (or a
  missing σ column of a measured component) is filled with those defaults, with an event.
* σ = 0 is floored to :data:`ZERO_POS_STD_FLOOR_M` / :data:`ZERO_VEL_STD_FLOOR_M_S` (the default floors
  of the filter configuration, ``gnss.min_pos_std_m`` / ``gnss.min_vel_std_m_s``) with a warning event:
  a zero σ claims a perfect measurement and makes the update singular (KF-GINS, OB_GINS users' reports).
* σ < 0 (or ±inf) is refused with :class:`DataError` naming the file, line and column.

**Quality and σ** (issue 38; the one statement of these rules, used by the readers and by
``filters.preprocess.gnss_arrays``). Every reader gives a quality in RTKLIB's code (:data:`QUALITY_NAMES`):

=============  ===  ================================================================================
format         Q    from
=============  ===  ================================================================================
RTKLIB .pos    Q    the file's Q column as it is
NMEA GGA       Q    GGA fix quality 4 → 1, 5 → 2, 9 → 3, 2 → 4, 1 and 3 → 5 (0, 6, 7, 8: not a fix)
UBX NAV-PVT    Q    carrSoln 2 → 1, 1 → 2, diffSoln → 4, else 5
ROS NavSatFix  Q    status GBAS_FIX (2) → 4, SBAS_FIX (1) → 3, FIX (0) → 5 (NO_FIX −1: skipped)
=============  ===  ================================================================================

σ, in this order: the σ the file states (RTKLIB sdn/sde/sdu, UBX hAcc/vAcc, NMEA GST, ROS
``position_covariance`` when ``position_covariance_type`` > 0: its diagonal, ENU); else, for NMEA, from
the GGA HDOP: σE = σN = HDOP × :data:`NMEA_UERE_M`, σU = 2 × HDOP × :data:`NMEA_UERE_M` (stated in the
events); else the filter's ``gnss.default_pos_std_m``. The filter then multiplies σ by
:func:`quality_std_factor`: ``gnss.float_std_factor`` for Q = 2 (RTK float), ``gnss.single_std_factor``
for Q = 5 (single), 1 for every other quality (fixed, SBAS, DGPS, PPP) — as the configuration documents.
"""

from __future__ import annotations

import numpy as np

from aidnav.io.errors import DataError

#: σ the filter uses when a file gives none (``LooseConfig().gnss.default_*``), ENU [m], [m/s]
DEFAULT_POS_STD_M = (1.0, 1.0, 2.0)
DEFAULT_VEL_STD_M_S = (0.1, 0.1, 0.2)
#: a σ of exactly 0 in a file is replaced by this value (``LooseConfig().gnss.min_*`` defaults)
ZERO_POS_STD_FLOOR_M = 0.05
ZERO_VEL_STD_FLOOR_M_S = 0.02
#: user equivalent range error [m] that turns an NMEA GGA HDOP into a position σ when the log has no GST
#: (σE = σN = HDOP·UERE, σU = 2·HDOP·UERE; the quality factors of the filter apply on top). A stated
#: assumption, not fitted on any data: the order of a single-frequency code range error after the
#: broadcast corrections.
NMEA_UERE_M = 1.0
#: RTKLIB's quality codes, the one quality scale of aidnav
QUALITY_NAMES = {1: "fixed", 2: "float", 3: "SBAS", 4: "DGPS", 5: "single", 6: "PPP"}


def quality_std_factor(quality, float_factor: float, single_factor: float) -> np.ndarray:
    """The σ multiplier per fix (see the module docstring): ``float_factor`` for Q = 2,
    ``single_factor`` for Q = 5, 1 otherwise."""
    q = np.asarray(quality)
    return np.where(q == 2, float(float_factor), np.where(q == 5, float(single_factor), 1.0))


def _where(ref) -> str:
    return f"line {ref}" if isinstance(ref, int | np.integer) else str(ref)


def check_velocity(path, vel: np.ndarray | None, names, line_of) -> None:
    """Refuse ±inf velocity values (NaN = not measured is fine). ``line_of(i)`` → file line of row i."""
    if vel is None:
        return
    bad = np.isinf(vel)
    if bad.any():
        i, j = np.argwhere(bad)[0]
        raise DataError(path, line_of(int(i)), f"{names[j]}: {vel[i, j]} is not a finite velocity "
                                               "(use NaN or an empty field for 'not measured')")


def check_std(path, std: np.ndarray | None, names, line_of, what: str, default, floor, unit: str,
              events: list[str], measured: np.ndarray | None = None) -> np.ndarray | None:
    """Validate and fill one (M, 3) σ array (ENU) read from ``path``; returns the array to store.

    names : the file's names of the three columns (for messages). measured : (M, 3) bool, where the
    quantity itself was measured (σ of unmeasured components may stay NaN). what : "position" or
    "velocity". default, floor : see the module docstring; unit : "m" or "m/s".
    """
    name = getattr(path, "name", str(path))
    if std is None:
        events.append(f"{name}: no {what} σ in the file: the filter's default "
                      f"gnss.default_{'pos_std_m' if what == 'position' else 'vel_std_m_s'} is used "
                      f"({', '.join(f'{v:g}' for v in default)} {unit} E, N, U unless configured)")
        return None
    std = np.array(std, dtype=float, copy=True)
    neg = std < 0
    if neg.any():
        i, j = np.argwhere(neg)[0]
        raise DataError(path, line_of(int(i)), f"{names[j]}: negative standard deviation "
                                               f"{float(std[i, j])!r} {unit} (a σ must be ≥ 0)")
    inf = np.isinf(std)
    if inf.any():
        i, j = np.argwhere(inf)[0]
        raise DataError(path, line_of(int(i)), f"{names[j]}: standard deviation {std[i, j]} is not finite")
    nan = np.isnan(std)
    if measured is not None:
        nan &= measured
    if nan.any():
        i, j = np.argwhere(nan)[0]
        std[nan] = np.broadcast_to(np.asarray(default, dtype=float), std.shape)[nan]
        events.append(f"{name}: {int(nan.sum())} {what} σ value(s) missing (first at "
                      f"{_where(line_of(int(i)))}, {names[j]}): the default "
                      f"{', '.join(f'{v:g}' for v in default)} {unit} (E, N, U) is used there")
    zero = std == 0
    if zero.any():
        i, j = np.argwhere(zero)[0]
        std[zero] = floor
        events.append(f"warning: {name}: {int(zero.sum())} {what} σ value(s) are 0 (first at "
                      f"{_where(line_of(int(i)))}, {names[j]}): floored to {floor:g} {unit}")
    return std
