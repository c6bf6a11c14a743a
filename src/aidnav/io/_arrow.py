"""Arrow → numpy without pandas.

``pyarrow.Array.to_numpy`` imports pandas (half a second of start-up and ~50 MB) even for a plain
float column; the readers on the fast paths use :func:`column_to_f64` instead.
"""

from __future__ import annotations

import numpy as np
import pyarrow as pa

_NUMPY = {pa.float64(): np.float64, pa.float32(): np.float32, pa.int64(): np.int64, pa.int32(): np.int32,
          pa.int16(): np.int16, pa.int8(): np.int8, pa.uint32(): np.uint32, pa.uint16(): np.uint16,
          pa.uint8(): np.uint8, pa.uint64(): np.uint64}


def column_to_f64(col, copy: bool = True) -> np.ndarray:
    """A numeric Arrow (chunked) array as a float64 numpy array; nulls become NaN.

    copy=False: a float64 column of one chunk without nulls is returned as a read-only view of the Arrow
    buffer (no copy; the buffer lives as long as the view), anything else as a new array."""
    chunks = col.chunks if isinstance(col, pa.ChunkedArray) else [col]
    if not copy and len(chunks) == 1 and chunks[0].type == pa.float64() and not chunks[0].null_count:
        c = chunks[0]
        return np.frombuffer(c.buffers()[1], dtype=np.float64)[c.offset:c.offset + len(c)]
    parts = []
    for c in chunks:
        dt = _NUMPY.get(c.type)
        if dt is None:  # not a plain numeric type: let pyarrow (and pandas) handle it
            parts.append(np.asarray(c.to_numpy(zero_copy_only=False), dtype=float))
            continue
        v = np.frombuffer(c.buffers()[1], dtype=dt)[c.offset:c.offset + len(c)].astype(float)
        if c.null_count:
            valid = np.unpackbits(np.frombuffer(c.buffers()[0], dtype=np.uint8), bitorder="little")
            v[~valid[c.offset:c.offset + len(c)].astype(bool)] = np.nan
        parts.append(v)
    if not parts:
        return np.zeros(0)
    return parts[0] if len(parts) == 1 else np.concatenate(parts)


def f64_to_arrow(values) -> pa.Array:
    """A 1-D numeric numpy array as an Arrow array (float64, or int64 for integer input), zero-copy and
    without ``pa.array`` (which imports pandas)."""
    a = np.asarray(values)
    if np.issubdtype(a.dtype, np.integer):
        a = np.ascontiguousarray(a, dtype=np.int64)
        return pa.Array.from_buffers(pa.int64(), len(a), [None, pa.py_buffer(a)])
    a = np.ascontiguousarray(a, dtype=np.float64)
    return pa.Array.from_buffers(pa.float64(), len(a), [None, pa.py_buffer(a)])


_FIXED = {"int32": (pa.int32(), np.int32), "int64": (pa.int64(), np.int64),
          "float64": (pa.float64(), np.float64)}


def to_arrow(values, kind: str) -> pa.Array:
    """``values`` (a sequence or 1-D array, no missing values) as an Arrow array of ``kind``: "int32",
    "int64", "float64", "bool" or "string", built from buffers: ``pa.array`` imports pandas on its
    first call (≈ 0.5 s and 50 MB in a process that has not), whatever it is given. The same array as
    ``pa.array(values, type)`` (a test compares them)."""
    if kind in _FIXED:
        typ, dt = _FIXED[kind]
        a = np.ascontiguousarray(np.asarray(values, dtype=dt))
        return pa.Array.from_buffers(typ, len(a), [None, pa.py_buffer(a)])
    if kind == "bool":
        a = np.asarray(values, dtype=bool)
        bits = pa.py_buffer(np.packbits(a, bitorder="little"))
        return pa.Array.from_buffers(pa.bool_(), len(a), [None, bits])
    if kind == "string":
        enc = [str(v).encode("utf-8") for v in values]
        off = np.zeros(len(enc) + 1, np.int32)
        np.cumsum([len(e) for e in enc], out=off[1:])
        data = pa.py_buffer(b"".join(enc))
        return pa.Array.from_buffers(pa.string(), len(enc), [None, pa.py_buffer(off), data])
    raise ValueError(f"to_arrow: kind must be int32, int64, float64, bool or string (got {kind!r})")
