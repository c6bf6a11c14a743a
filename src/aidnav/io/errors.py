"""Errors raised by the readers: they always name the file, the line (when known) and the problem."""

from __future__ import annotations

from aidnav.errors import InputError


class DataError(InputError):
    """Bad input data: ``DataError(path, line, problem)`` → "path:line: problem"."""

    def __init__(self, path, line: int | None, problem: str):
        self.path = str(path)
        self.line = line
        self.problem = problem
        where = f"{self.path}:{line}" if line is not None else self.path
        super().__init__(f"{where}: {problem}")
