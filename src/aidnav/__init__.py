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

A reference "§x.y" (or "models.md §x.y") in a comment is a section of ``docs/models.md``: the models and
the errata aidnav follows, in our words, numbered as the project's specification.

Layers (each imports only those to its left): ``nav < sim | filters < estimators < analysis <
report < experiments < apps < cli``; ``aidnav.io`` and ``aidnav.data`` sit beside ``nav``.
"""

import os as _os


def _gettempdir() -> str:
    import tempfile  # lazy: only on a read-only install; `import aidnav` stays fast

    return tempfile.gettempdir()


def _numba_cache_dir() -> str | None:
    """numba writes its cache (``cache=True``) beside the sources; where that is not writable (a
    read-only install) and ``NUMBA_CACHE_DIR`` is unset, use a user cache directory instead, or a
    temporary one. Returns the directory chosen, or None when the default is used."""
    if _os.environ.get("NUMBA_CACHE_DIR"):
        return None
    here = _os.path.dirname(_os.path.abspath(__file__))
    probe = _os.path.join(here, "nav", "__pycache__")
    target = probe if _os.path.isdir(probe) else here
    if _os.access(target, _os.W_OK | _os.X_OK):
        return None
    for base in (_os.environ.get("XDG_CACHE_HOME") or _os.path.join(_os.path.expanduser("~"), ".cache"),
                 _gettempdir()):
        d = _os.path.join(base, "aidnav-numba")
        try:
            _os.makedirs(d, exist_ok=True)
        except OSError:
            continue
        if _os.access(d, _os.W_OK | _os.X_OK):
            # a normal set-up (a system-wide install), not a problem: no warning on every command (issue
            # 37); the directory chosen is NUMBA_CACHE_FALLBACK (and NUMBA_CACHE_DIR)
            _os.environ["NUMBA_CACHE_DIR"] = d
            return d
    return None


NUMBA_CACHE_FALLBACK = _numba_cache_dir()

def __getattr__(name: str):
    # the version is looked up on first use: importlib.metadata costs ~20 ms of every command's start
    if name == "__version__":
        from importlib.metadata import PackageNotFoundError, version  # lazy: ~20 ms of start-up

        try:
            v = version("aidnav")
        except PackageNotFoundError:  # a source tree that is not installed
            v = "0+unknown"
        globals()["__version__"] = v
        return v
    raise AttributeError(f"module 'aidnav' has no attribute {name!r}")


__all__ = ["__version__"]
