"""Output files that appear whole or not at all, and the run status of an output directory (issue 37).

Every output file is written under a temporary name (``NAME.part`` beside it) and renamed into place
when complete (:func:`replacing`, :func:`write_text`): a run killed while writing leaves at most a
``.part`` file, never a truncated file under the real name. A job marks its directory first
(``summary.json`` with ``"status": "running"``, :func:`mark_running`, which also removes the outputs a
previous run left there and the stale ``.part``/``tmp*.spool`` files of a killed one) and writes the
final summary with ``"status": "complete"`` last; :func:`check_complete` is what the readers
(``evaluate``, ``report``) ask before they trust a file of such a directory.
"""

from __future__ import annotations

import contextlib
import json
import os
from pathlib import Path

from aidnav.errors import InputError

__all__ = ["replacing", "write_text", "remove_stale", "mark_running", "check_complete", "SUMMARY",
           "IncompleteRunError"]

#: the file that holds a run's status (``running`` while it runs, ``complete`` when done)
SUMMARY = "summary.json"


class IncompleteRunError(InputError):
    """A file of a run that did not complete (exit 2: rerun the job)."""


def part_path(path) -> Path:
    path = Path(path)
    return path.with_name(path.name + ".part")


@contextlib.contextmanager
def replacing(path):
    """``with replacing(path) as tmp:`` write ``tmp``; on success it is renamed to ``path`` (atomic on one
    file system), on any exception (Ctrl-C included) it is removed and ``path`` is left as it was."""
    path = Path(path)
    tmp = part_path(path)
    try:
        yield tmp
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise


def write_text(path, text: str, encoding: str = "utf-8") -> Path:
    """``path.write_text(text)`` through a temporary name (:func:`replacing`)."""
    with replacing(path) as tmp:
        tmp.write_text(text, encoding=encoding)
    return Path(path)


def remove_stale(directory, names=()) -> list[Path]:
    """Remove from ``directory`` the leftovers of a killed run (``*.part``, ``tmp*.spool``) and the files
    ``names`` (outputs of a previous run that this one replaces); returns what was removed."""
    d = Path(directory)
    gone = []
    if not d.is_dir():
        return gone
    stale = [*d.glob("*.part"), *d.glob("tmp*.spool"), *(d / n for n in names)]
    for p in stale:
        try:
            if p.is_file():
                p.unlink()
                gone.append(p)
        except OSError:
            pass
    return gone


def mark_running(directory, job: str, outputs=(), **fields) -> Path:
    """Mark ``directory`` as holding a run in progress: remove stale leftovers and the previous run's
    ``outputs`` (:func:`remove_stale`), then write ``summary.json`` = ``{"status": "running", "job": …}``.
    The job's final summary (with ``"status": "complete"``) replaces it when the run completes."""
    remove_stale(directory, outputs)
    return write_text(Path(directory) / SUMMARY, json.dumps({"status": "running", "job": job, **fields},
                                                            indent=2) + "\n")


def run_status(directory) -> str | None:
    """The status in ``directory/summary.json``: ``running``, ``complete``; None where there is no
    summary or it has no status (written before issue 37: taken as complete)."""
    p = Path(directory) / SUMMARY
    try:
        doc = json.loads(p.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None if not p.exists() else "unreadable"
    return doc.get("status") if isinstance(doc, dict) else "unreadable"


def check_complete(path, what: str = "the estimate") -> None:
    """Refuse a file of a run directory whose run did not complete (its ``summary.json`` says
    ``running``, or is unreadable) or that the completed run did not write (a stale file of an earlier
    run): raises :class:`IncompleteRunError` naming the directory and what to do."""
    path = Path(path)
    d = path if path.is_dir() else path.parent
    st = run_status(d)
    if st is None or st == "complete":
        if st == "complete" and path.is_file():
            doc = json.loads((d / SUMMARY).read_text(encoding="utf-8"))
            written = doc.get("files")
            if isinstance(written, list) and path.name not in written and path.name != SUMMARY:
                raise IncompleteRunError(
                    f"{path}: {what} is not an output of the run that completed in {d} (its summary.json "
                    f"lists {', '.join(written)}): a stale file of an earlier run — delete it, or rerun "
                    "the job into an empty directory")
        return
    if st == "unreadable":
        raise IncompleteRunError(f"{d / SUMMARY}: cannot read the run's summary: the run in {d} may not "
                                 f"have completed — rerun it before using {path.name}")
    raise IncompleteRunError(f"{path}: the run in {d} did not complete (summary.json status '{st}': it "
                             "was interrupted or failed): its outputs are partial or stale — rerun the "
                             "job to completion first")
