"""Unit normals keyed by flight segment: common random numbers across trajectory variants.

A Monte Carlo that compares trajectory variants (a straight leg inserted, a leg made longer, another
maneuver before the same legs) resolves their differences far better when each variant sees the *same*
noise on the segments they share (common random numbers). Drawing one stream over the whole run gives
that only on a shared prefix: inserting a leg shifts every later draw. Here the draws of the samples in
a segment come from a child stream of the run seed keyed by the segment's name (and the stream's
number), in order from the segment's start: two variants that both fly a segment named ``AB`` get the
same draws on ``AB`` over the samples they share (the first ``min`` of their lengths), whatever precedes
it. Within one run the segments' draws are independent (distinct keys; a name used twice gets its
occurrence count in the key).
"""

from __future__ import annotations

import zlib

import numpy as np

__all__ = ["segment_normals"]


def _child(seed: np.random.SeedSequence, *key: int) -> np.random.Generator:
    return np.random.default_rng(np.random.SeedSequence(seed.entropy,
                                                        spawn_key=tuple(seed.spawn_key) + tuple(key)))


def segment_normals(seed: np.random.SeedSequence, stream: int, time: np.ndarray, segments,
                    tail=()) -> np.ndarray:
    """Unit normals of shape (len(time), *tail), keyed by segment.

    seed: the run's seed sequence; stream: a number distinguishing the noise sources of a run;
    time: sample times [s] (increasing); segments: the ``[{name, start_s, end_s}, ...]`` list of
    :func:`aidnav.sim.trajectory.generate_truth` (None or empty: one stream for all samples).
    A sample at t belongs to the last segment with start_s ≤ t (samples before the first segment to
    the first). Row j of a segment's block is the j-th sample of that segment in ``time``.
    """
    t = np.asarray(time, float)
    tail = tuple(int(x) for x in tail)
    if not segments:
        return _child(seed, stream, 0).standard_normal((len(t), *tail))
    starts = np.array([float(s["start_s"]) for s in segments])
    which = np.clip(np.searchsorted(starts, t + 1e-9, side="right") - 1, 0, len(segments) - 1)
    out = np.empty((len(t), *tail))
    seen: dict[str, int] = {}
    for i, s in enumerate(segments):
        name = str(s["name"])
        seen[name] = seen.get(name, -1) + 1
        rows = np.flatnonzero(which == i)
        if len(rows):
            key = zlib.crc32(f"{name}#{seen[name]}".encode())
            out[rows] = _child(seed, stream, 1, key).standard_normal((len(rows), *tail))
    return out
