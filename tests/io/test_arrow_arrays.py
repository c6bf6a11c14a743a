"""Arrow arrays built from buffers (:func:`aidnav.io._arrow.to_arrow`) are ``pa.array``'s, and making them
does not import pandas (``pa.array`` does: half a second of every campaign's merge, issue 41)."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pyarrow as pa
import pytest

from aidnav.io._arrow import to_arrow


def test_to_arrow_is_pa_array():
    cases = [([3, -1, 2**31 - 1], "int32", pa.int32()), ([2**40, 0], "int64", pa.int64()),
             (np.array([0.5, np.nan, -np.inf]), "float64", pa.float64()),
             ([True, False, True] * 5, "bool", pa.bool_()),
             (["a", "", "déjà vu", "x" * 300], "string", pa.string()),
             ([], "string", pa.string()), (np.zeros(0, np.int32), "int32", pa.int32())]
    for values, kind, typ in cases:
        got = to_arrow(values, kind)
        got.validate(full=True)
        want = pa.array(list(values), typ)
        assert got.type == want.type and got.null_count == want.null_count == 0, (kind, values)
        assert repr(got.to_pylist()) == repr(want.to_pylist()), (kind, values)  # (NaN: equals says no)
    with pytest.raises(ValueError, match="kind"):
        to_arrow([1], "int8")


def test_to_arrow_does_not_import_pandas():
    code = ("import sys; from aidnav.io._arrow import to_arrow; import pyarrow as pa; "
            "pa.table({'a': to_arrow(['x'], 'string'), 'b': to_arrow([1.0], 'float64')}); "
            "print('pandas' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False", out.stderr
