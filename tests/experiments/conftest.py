"""Fixtures of the experiment tests: tiny experiment files and campaigns computed once per session."""

from __future__ import annotations

import copy
from pathlib import Path

import pytest
import yaml

REPO = Path(__file__).resolve().parents[2]
QUICK = REPO / "examples" / "experiment_quick.yaml"

#: A tiny campaign (2 sweep points x 3 runs of a 40 s flight): fast enough to run on several backends.
TINY = {
    "name": "tiny",
    "scenario": {
        "initial": {"lat_deg": 30.0, "lon_deg": 114.0, "height_m": 500.0, "speed_m_s": 50.0,
                    "heading_deg": 10.0},
        "imu_rate_hz": 100,
        "transition_s": 2,
        "segments": [{"type": "straight", "duration_s": 15, "name": "AB"},
                     {"type": "u_turn", "duration_s": 10, "name": "U"},
                     {"type": "straight", "duration_s": 15, "name": "CD"}],
    },
    "sensors": {"imu": {"grade": "tactical"}, "gnss": {"rate_hz": 2}},
    "estimators": [{"name": "loose", "type": "loose"}],
    "runs": 3,
    "base_seed": 7,
    "sweep": {"imu.grade": ["tactical", "mems"]},
    "statistics": {"quantities": ["pos_h", "vel_h", "heading"],
                   "windows": {"AB": {"segment": "AB"}, "CD": {"segment": "CD"}, "last5": {"last_s": 5}},
                   "convergence": {"h1": {"quantity": "heading", "below": 1.0}}},
}


def write_experiment(path: Path, doc: dict | None = None, **changes) -> Path:
    """Write ``doc`` (default: TINY) with top-level ``changes`` as YAML; return the path."""
    d = copy.deepcopy(TINY if doc is None else doc)
    d.update(changes)
    path.write_text(yaml.safe_dump(d, sort_keys=False))
    return path


@pytest.fixture
def tiny_doc() -> dict:
    """A fresh copy of the TINY experiment document."""
    return copy.deepcopy(TINY)


@pytest.fixture
def write_exp():
    """The :func:`write_experiment` helper."""
    return write_experiment


@pytest.fixture(scope="session")
def quick_file() -> Path:
    return QUICK


@pytest.fixture(scope="session")
def tiny_file(tmp_path_factory) -> Path:
    return write_experiment(tmp_path_factory.mktemp("tiny") / "tiny.yaml")


@pytest.fixture(scope="session")
def tiny_serial(tiny_file, tmp_path_factory):
    """The tiny campaign computed serially: (directory, CampaignResult)."""
    from aidnav.experiments.runner import run_experiment

    out = tmp_path_factory.mktemp("tiny_serial")
    res = run_experiment(tiny_file, out, progress=False)
    return out, res


@pytest.fixture(scope="session")
def quick_campaign(tmp_path_factory):
    """examples/experiment_quick.yaml computed serially and reported: (directory, CampaignResult)."""
    from aidnav.experiments.report import write_report
    from aidnav.experiments.runner import run_experiment

    out = tmp_path_factory.mktemp("quick")
    res = run_experiment(QUICK, out, progress=False)
    write_report(out)
    return out, res
