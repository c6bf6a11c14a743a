"""aidnav: aided inertial navigation.

Strapdown INS mechanization aided by GNSS (loosely and tightly coupled), by satcom antennas and by a
master navigation system; simulation, estimation, evaluation and reporting around it.

Conventions (full text: ``docs/conventions.md``):

* frames: navigation frame ENU (East, North, Up); body = IMU axes RFU (Right, Forward, Up);
* attitude: ``C_b^n`` maps body to nav; user angles (roll, pitch, heading) in degrees, heading
  clockwise from true North in [0, 360); quaternions Hamilton, scalar first; attitude error φ with
  ``C_est = (I − [φ×]) C_true``; other error states are estimate − truth;
* units: radians and SI inside, degrees and named units (``_deg``, ``_deg_h``, ``_ug``) only in files
  and on screen; heights above the WGS-84 ellipsoid;
* IMU samples are increments Δθ [rad], Δv [m/s] over (t_{k−1}, t_k], stamped at t_k;
* time: float seconds, GPS seconds of week for GNSS-timed data; outputs keep their inputs' scale;
* every unit, frame, time and datum conversion happens once, in :mod:`aidnav.io`.

Layers (each imports only those to its left): ``nav < sim | filters < estimators < analysis <
report < experiments < apps < cli``; ``aidnav.io`` and ``aidnav.data`` sit beside ``nav``.
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("aidnav")
except PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0+unknown"

__all__ = ["__version__"]
