"""Flight-trajectory design for a distributed POS (seed 004): rank candidate trajectories by the
predicted accuracy of the transfer alignment, from the filter covariance alone (no Monte Carlo).

For each candidate (a :class:`~aidnav.sim.scenario.Scenario`, a scenario file, or the
``(truth, imu, segments)`` of :func:`aidnav.sim.trajectory.generate_truth`) the truth trajectory is
generated and the transfer-alignment covariance recursion (:func:`aidnav.filters.transfer.
covariance_analysis`: the same F, Φ, Qd, H and Joseph update as the filter, evaluated on the truth)
is run once. The predicted 1σ of the sub-IMU's roll, pitch and heading errors is summarised over the
imaging legs (default AB and CD) as the root mean square of σ over each leg, averaged over the legs:
the prediction of the Monte Carlo RMS error of those legs. A candidate takes about a second
(trajectory generation included), against minutes for a Monte Carlo of ten runs.

What it predicts, and what it does not: the covariance is the ensemble spread of a consistent filter,
so it predicts the RMS error over runs; the seed's "STD" (the standard deviation of each run's error
over a leg) leaves out the part of the error that is constant over the leg. Where a maneuver makes
the heading observable before the leg, both are close; where it does not (no maneuver), the heading
error is a slowly changing offset and the covariance predicts it, the per-leg STD does not. The
seed-004 reproduction (``aidnav.experiments.reproduce.seed_004``) compares both rankings with the
Monte Carlo.

Units: angles in degrees in the returned rows (``*_deg``), radians inside.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from aidnav.filters.transfer import CovarianceAnalysis, TransferConfig, covariance_analysis
from aidnav.sim.distributed_pos import MasterPosSpec

__all__ = ["predict_accuracy", "rank_trajectories"]


def _bundle(candidate):
    from aidnav.sim.scenario import Scenario, load_scenario
    from aidnav.sim.trajectory import generate_truth

    if isinstance(candidate, tuple):
        return candidate
    if isinstance(candidate, (str, Path)):
        candidate = load_scenario(candidate)
    if isinstance(candidate, Scenario):
        return generate_truth(candidate)
    raise TypeError(f"rank_trajectories: a candidate must be a Scenario, a path or a generate_truth tuple, "
                    f"not {type(candidate).__name__}")


def predict_accuracy(candidate, cfg: TransferConfig | None = None, master: MasterPosSpec | None = None,
                     legs=("AB", "CD")) -> tuple[dict, CovarianceAnalysis]:
    """Predicted sub-IMU attitude accuracy on the imaging ``legs`` of one candidate trajectory.

    Returns ``(row, analysis)``: row = {roll_deg, pitch_deg, heading_deg} (mean over the legs of the
    RMS of the predicted 1σ [deg]) and the :class:`~aidnav.filters.transfer.CovarianceAnalysis`.
    """
    ana = covariance_analysis(_bundle(candidate), cfg, master)
    rms = np.degrees(ana.segment_rms(legs))
    return {"roll_deg": float(rms[0]), "pitch_deg": float(rms[1]), "heading_deg": float(rms[2])}, ana


def rank_trajectories(candidates: dict, cfg: TransferConfig | None = None,
                      master: MasterPosSpec | None = None, legs=("AB", "CD"),
                      key: str = "heading_deg") -> list[dict]:
    """Rank candidate trajectories by predicted accuracy (best first).

    candidates: {name: Scenario | path | (truth, imu, segments)}; every candidate needs segments named
    as in ``legs``. cfg: filter settings (default :class:`~aidnav.filters.transfer.TransferConfig`,
    24 states, the seed's sub-IMU and master). key: the column to rank by.
    Returns rows {name, rank, roll_deg, pitch_deg, heading_deg} sorted by ``key``.
    """
    rows = []
    for name, cand in candidates.items():
        row, _ = predict_accuracy(cand, cfg, master, legs)
        rows.append({"name": name, **row})
    rows.sort(key=lambda r: r[key])
    for i, r in enumerate(rows):
        r["rank"] = i + 1
    return rows
