"""The plain dispatch of :func:`aidnav.filters.measurements.fill` against the model table: every id calls
the table's function for it (and nothing else), an unknown id gives no rows. Run on ``fill``'s Python
function with each model replaced by a marker (the dispatch reads the models from the module's globals)."""

from __future__ import annotations

import numpy as np

from aidnav.filters import measurements as ms


def test_fill_dispatches_every_id_to_its_table_entry(monkeypatch):
    py_fill = getattr(ms.fill, "py_func", ms.fill)
    assert len(ms.MODELS) == len(ms.MODEL_NAMES) == ms.N_MODELS
    names = {}
    for name, value in vars(ms).items():
        for i, model in enumerate(ms.MODELS):
            if value is model:
                names.setdefault(i, []).append(name)
    assert sorted(names) == list(range(ms.N_MODELS)), "a model of the table is not a name of the package"
    for i in range(ms.N_MODELS):
        for name in names[i]:
            monkeypatch.setattr(ms, name, lambda *a, _i=i: 100 + _i)
    for i in range(ms.N_MODELS):
        assert py_fill(i, None, None, None, None, None, None, None) == 100 + i, ms.MODEL_NAMES[i]
    assert py_fill(ms.N_MODELS, None, None, None, None, None, None, None) == 0
    assert py_fill(-1, None, None, None, None, None, None, None) == 0


def test_models_key_follows_the_sources():
    assert len(ms.MODELS_KEY) == 20 and ms.MODELS_KEY == ms._sources_key()
    assert isinstance(ms.M_MAG, int) and ms.MODEL_NAMES[ms.M_MAG] == "mag_heading"
    assert np.all(np.diff([ms.M_GNSS_POS, ms.M_GNSS_VEL, ms.M_MAG]) > 0)
