"""Issue 24: no numba kernel of the filters and estimators takes more than 10 arguments (parameters and
results travel as named tuples). Inspects every njit function defined in an aidnav.filters or
aidnav.estimators module."""

from __future__ import annotations

import importlib
import inspect
import pkgutil

from numba.core.registry import CPUDispatcher

import aidnav.estimators
import aidnav.filters

MAX_ARGS = 10


def _kernels():
    for pkg in (aidnav.filters, aidnav.estimators):
        for info in pkgutil.walk_packages(pkg.__path__, pkg.__name__ + "."):
            mod = importlib.import_module(info.name)
            for name, obj in vars(mod).items():
                if isinstance(obj, CPUDispatcher) and obj.py_func.__module__ == mod.__name__:
                    yield f"{info.name}.{name}", obj.py_func


def test_kernels_found():
    names = dict(_kernels())
    assert "aidnav.filters.engine.run_filter" in names and "aidnav.filters.ins_errors.fill_model" in names
    assert len(names) > 50


def test_no_kernel_has_more_than_ten_arguments():
    wide = {name: len(inspect.signature(f).parameters) for name, f in _kernels()
            if len(inspect.signature(f).parameters) > MAX_ARGS}
    assert not wide, f"kernels with more than {MAX_ARGS} arguments (use named tuples): {wide}"
