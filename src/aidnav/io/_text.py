"""Headerless numeric text tables (KF-GINS style): fields separated by any of ``,``, space, tab."""

from __future__ import annotations

import io
import re
from pathlib import Path

import numpy as np

from aidnav.io.errors import DataError

_SPLIT = re.compile(r"[,\s]+")


def read_numeric_text(path, allowed_columns: tuple[int, ...], what: str) -> tuple[np.ndarray, np.ndarray]:
    """Read a headerless table of numbers → (values (N, k) float64, 1-based file line of each row).

    Lines that are blank or start with ``#`` or ``%`` are skipped. Every data line must have the same
    number of fields, one of ``allowed_columns``; a field that is not a number, a different field count
    or a NaN/inf value raises :class:`DataError` naming the line. ``what`` names the format in messages.
    """
    path = Path(path)
    try:
        raw = path.read_bytes()
    except OSError as e:
        raise DataError(path, None, f"cannot read file: {e.strerror or e}") from None
    text = raw.decode("utf-8", errors="replace")
    lines = text.split("\n")
    data_idx = [i for i, ln in enumerate(lines)
                if ln.strip() and not ln.lstrip().startswith(("#", "%"))]
    if not data_idx:
        raise DataError(path, None, f"empty file (no {what} lines)")
    body = "\n".join(_SPLIT.sub(" ", lines[i].strip()) for i in data_idx)
    line_no = np.asarray(data_idx, dtype=np.int64) + 1
    k = len(_SPLIT.split(lines[data_idx[0]].strip()))
    if k not in allowed_columns:
        raise DataError(path, int(line_no[0]), f"{k} fields; a {what} file has "
                                               f"{' or '.join(str(c) for c in allowed_columns)}")
    counts = np.fromiter((len(_SPLIT.split(lines[i].strip())) for i in data_idx), dtype=np.int64,
                         count=len(data_idx))
    bad = counts != k
    if bad.any():
        j = int(np.argmax(bad))
        raise DataError(path, int(line_no[j]), f"{counts[j]} fields, expected {k} (as on line {line_no[0]})")
    import pandas as pd  # lazy: pandas is heavy to import

    df = pd.read_csv(io.StringIO(body), sep=" ", header=None, dtype=str, engine="c", keep_default_na=False)
    vals = np.column_stack([pd.to_numeric(df[c], errors="coerce").to_numpy(float) for c in df.columns])
    unreadable = np.isnan(vals) & ~df.apply(lambda s: s.str.lower().isin(["nan", "-nan", "+nan"])).to_numpy()
    if unreadable.any():
        r, c = np.argwhere(unreadable)[0]
        raise DataError(path, int(line_no[r]), f"field {c + 1}: not a number: {df.iat[r, c]!r}")
    nonfinite = ~np.isfinite(vals)
    if nonfinite.any():
        r, c = np.argwhere(nonfinite)[0]
        raise DataError(path, int(line_no[r]), f"field {c + 1}: {vals[r, c]} (values must be finite numbers)")
    return vals, line_no


def check_increasing(path, t: np.ndarray, line_no: np.ndarray, what: str = "time") -> None:
    """DataError at the first sample whose time does not increase."""
    d = np.diff(t)
    bad = ~(d > 0)
    if bad.any():
        i = int(np.argmax(bad)) + 1
        kind = "duplicate time" if d[i - 1] == 0 else "time goes backwards"
        raise DataError(path, int(line_no[i]), f"{what} not strictly increasing ({kind}): "
                                               f"{float(t[i])!r} s after {float(t[i - 1])!r} s at line "
                                               f"{int(line_no[i - 1])}")
