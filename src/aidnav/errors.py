"""The one base class of errors that are the user's to fix (bad input, bad option, bad config).

Every command turns an :class:`InputError` into ``error: FILE:LINE: what is wrong — what to do`` and
exit status 2; anything else escaping a command is a bug in aidnav (exit status 1).
"""

from __future__ import annotations


class InputError(ValueError):
    """A problem with what the user gave us (file, option, configuration), not a bug."""


class DivergenceError(InputError):
    """The filter output is not a navigation solution (NaN/inf, jumps, σ without bound)."""
