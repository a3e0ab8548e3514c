"""The evaluation's recording cache stays under its size limit (evaluation/cachesize.py)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from depthtouch.errors import ConfigError
from depthtouch.evaluation.cachesize import (
    CACHE_MAX_ENV,
    DEFAULT_MAX_GB,
    cache_limit_bytes,
    mark_used,
    prune,
)


def _entry(folder: Path, stem: str, size: int, mtime: float) -> Path:
    rec = folder / f"{stem}.npz"
    rec.write_bytes(b"r" * size)
    (folder / f"{stem}.truth.json").write_bytes(b"t" * 10)
    os.utime(rec, (mtime, mtime))
    return rec


def test_the_least_recently_used_recordings_go_first_until_the_folder_fits(tmp_path: Path
                                                                           ) -> None:
    old = _entry(tmp_path, "a-1", 1000, 100.0)
    mid = _entry(tmp_path, "b-2", 1000, 200.0)
    new = _entry(tmp_path, "c-3", 1000, 300.0)
    writing = tmp_path / "d-4.part77.npz"
    writing.write_bytes(b"p" * 5000)
    (tmp_path / "notes.txt").write_text("kept")
    assert prune(tmp_path, 3030) == []  # 3 x (1000 + 10) bytes fit
    assert prune(tmp_path, 2100) == [old]
    assert not old.exists() and not (tmp_path / "a-1.truth.json").exists()
    assert mid.exists() and new.exists() and writing.exists()
    assert (tmp_path / "notes.txt").read_text() == "kept"


def test_the_recording_just_written_is_kept_even_when_it_alone_is_too_large(tmp_path: Path
                                                                           ) -> None:
    a = _entry(tmp_path, "a-1", 1000, 100.0)
    b = _entry(tmp_path, "b-2", 1000, 50.0)  # the oldest, but just written
    assert prune(tmp_path, 10, keep=b) == [a]
    assert b.exists() and (tmp_path / "b-2.truth.json").exists()


def test_a_recording_read_from_the_cache_counts_as_recently_used(tmp_path: Path) -> None:
    a = _entry(tmp_path, "a-1", 1000, 100.0)
    b = _entry(tmp_path, "b-2", 1000, 200.0)
    mark_used(a)
    assert a.stat().st_mtime > 200.0
    assert prune(tmp_path, 1500) == [b]


def test_the_limit_comes_from_the_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(CACHE_MAX_ENV, raising=False)
    assert cache_limit_bytes() == int(DEFAULT_MAX_GB * 1e9)
    monkeypatch.setenv(CACHE_MAX_ENV, "2.5")
    assert cache_limit_bytes() == 2_500_000_000
    monkeypatch.setenv(CACHE_MAX_ENV, "0")
    assert cache_limit_bytes() is None
    for bad in ("lots", "-1", "nan", "inf"):
        monkeypatch.setenv(CACHE_MAX_ENV, bad)
        with pytest.raises(ConfigError, match=CACHE_MAX_ENV) as e:
            cache_limit_bytes()
        assert "\n" not in str(e.value)
