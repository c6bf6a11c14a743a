"""IMU noise characterisation: Allan deviation of a static log → fitted noise terms → filter settings.

Frames and units. Input increments Δθ [rad], Δv [m/s] (body RFU, :class:`aidnav.data.ImuData`) or rates
[rad/s], [m/s²] on arrays. Inside, everything is SI; the results are given back in boundary units: ARW
[deg/√h], VRW [m/s/√h], gyro bias instability [deg/h], accelerometer bias instability [µg], rate random
walk [deg/h/√h], acceleration random walk [µg/√h], correlation times [s], quantisation noise coefficient
Q [rad] / [m/s] (IEEE 952: σ² = 3Q²/τ²; quantum = √12·Q).

The modules, in the order of the data:

- :mod:`.prepare` — uniform rates from increments (gaps cut, jitter resampled by cumulative-sum
  interpolation), trapezoid increments inverted to the sensor's samples;
- :mod:`.static` — static check (motion, slow motion, disturbance) and the longest static part;
- :mod:`aidnav.analysis.allan` — the overlapping Allan deviation (one fused numba pass per axis);
- :mod:`.model` — the four-term noise model and the unit constants;
- :mod:`.allan_cov` — exact covariance of the Allan variance estimates (EDFs and correlations);
- :mod:`.nnls` — numba kernels of the fit; :mod:`.fit` — the fit with its profile-likelihood intervals
  (:mod:`.roots`: its bracketing root finder);
- :mod:`.vibration` — sample spread and dominant frequency per axis;
- :mod:`.analyse` — :func:`characterise_rates` / :func:`characterise_imu`, the whole analysis;
- :mod:`.results` — the result containers; :mod:`.output` — noise.json, the ``imu:`` section, its YAML;
- :mod:`.file_job` — ``aidnav characterise`` on a file; :mod:`.console` — the console summary.

The figure (allan.png) is drawn by :func:`aidnav.report.allan_plot.plot_allan`, passed to
:func:`characterise_file` by its caller: analysis does not import report.

The names below are imported from their modules on first use (PEP 562): importing one module of the
package (the result containers and the model, for the figure's process of ``aidnav characterise``) does
not import the others (numba, scipy, rich: ~0.3 s).
"""

from __future__ import annotations

import importlib

#: where each name of the package is defined (imported on first use)
_WHERE = {
    "characterise_imu": "analyse", "characterise_rates": "analyse",
    "print_characterisation": "console",
    "characterise_file": "file_job", "imu_log_format": "file_job",
    "fit_allan": "fit",
    **dict.fromkeys(("AXES", "B_PER_GM_SIGMA", "FLICKER_ADEV", "GM_PEAK_ADEV", "GM_PEAK_X", "gm_avar",
                     "model_avar"), "model"),
    **dict.fromkeys(("auto_grade", "imu_section", "imu_yaml", "merge_gm_rw", "noise_dict"), "output"),
    **dict.fromkeys(("resampled_min_m", "trapezoid_samples", "uniform_rates"), "prepare"),
    **dict.fromkeys(("AxisFit", "Characterisation", "NotStaticError", "TermEstimate"), "results"),
    "static_check": "static",
    "vibration_report": "vibration",
    # re-exported: the units of the results
    **dict.fromkeys(("DEG_H", "DEG_H_SQRT_H", "DEG_SQRT_H", "M_S_SQRT_H", "UG", "UG_SQRT_H"), "aidnav.units"),
}

__all__ = ["characterise_imu", "characterise_rates", "fit_allan", "merge_gm_rw", "print_characterisation",
           "Characterisation", "AxisFit", "TermEstimate", "NotStaticError", "static_check", "uniform_rates",
           "imu_section", "imu_yaml", "noise_dict", "characterise_file", "imu_log_format", "gm_avar",
           "model_avar", "auto_grade", "resampled_min_m", "trapezoid_samples", "vibration_report", "AXES",
           "B_PER_GM_SIGMA", "GM_PEAK_X", "GM_PEAK_ADEV", "FLICKER_ADEV", "DEG_H", "DEG_SQRT_H",
           "DEG_H_SQRT_H", "UG", "UG_SQRT_H", "M_S_SQRT_H"]


def __getattr__(name: str):
    where = _WHERE.get(name)
    if where is None:  # a module of the package not imported yet (``noise_fit.fit``, as before)
        if name.startswith("_"):
            raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
        try:
            return importlib.import_module(f"{__name__}.{name}")
        except ModuleNotFoundError as e:
            if e.name != f"{__name__}.{name}":
                raise
            raise AttributeError(f"module {__name__!r} has no attribute {name!r}") from None
    mod = importlib.import_module(where if "." in where else f"{__name__}.{where}")
    value = getattr(mod, name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(__all__))
