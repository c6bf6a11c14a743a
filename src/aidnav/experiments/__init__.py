"""Experiments: Monte Carlo campaigns over sweeps of scenarios, sensors and estimators; paper reproductions.

* :mod:`aidnav.experiments.config` — experiment files (YAML, pydantic): :func:`load_experiment`,
  :class:`ExperimentError`, sweep points.
* :mod:`aidnav.experiments.estimators` — the estimator registry (``register_estimator``; ``loose`` built in).
* :mod:`aidnav.experiments.runner` — :func:`run_experiment` (serial, local processes, Dask), resumable.
* :mod:`aidnav.experiments.store` — run files and the Parquet tables (runs.parquet, epochs.parquet).
* :mod:`aidnav.experiments.report` — :func:`write_report` (self-contained HTML).
* :mod:`aidnav.experiments.reproduce` — ``aidnav reproduce SEED`` dispatcher and ``summary.json`` helper.

Nothing is imported here, so that ``import aidnav.experiments`` stays cheap (workers import what they use).
"""
