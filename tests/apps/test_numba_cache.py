"""An unwritable package directory must not break every command: numba's cache moves to a user
cache directory (``NUMBA_CACHE_DIR``), without a warning (a read-only install is a normal set-up)."""

from __future__ import annotations

import os
import warnings

import aidnav


def test_unwritable_package_dir_moves_numba_cache(monkeypatch, tmp_path):
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    pkg = os.path.dirname(aidnav.__file__)
    real_access = os.access

    def access(path, mode):
        if str(path).startswith(pkg):
            return False
        return real_access(path, mode)

    monkeypatch.setattr(aidnav._os, "access", access)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        d = aidnav._numba_cache_dir()
    assert d == str(tmp_path / "aidnav-numba")
    assert os.environ["NUMBA_CACHE_DIR"] == d
    assert os.path.isdir(d)


def test_writable_package_dir_keeps_default(monkeypatch):
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    monkeypatch.setattr(aidnav._os, "access", lambda path, mode: True)
    assert aidnav._numba_cache_dir() is None
    assert "NUMBA_CACHE_DIR" not in os.environ
