"""The evaluation's cache of rendered recordings stays under a size limit.

Each cached recording is keyed by its case and by a digest of the simulator's code
(:func:`depthtouch.evaluation.suite.recording_paths`), so every change to the simulator leaves
the older recordings behind, unused. Other frame rates and resolutions add copies of whole suites.
Without a limit the cache grew to 64 GB on a development machine and filled its disk.

After each new recording is written, the least recently used recordings of its folder are
deleted until the folder holds at most ``$DEPTHTOUCH_CACHE_MAX_GB`` (default
:data:`DEFAULT_MAX_GB`; 0: no limit). A recording read from the cache is marked used (its
modification time is set to now), so the suites in use stay and the stale ones go first. Every
entry can be rendered again; nothing else in the cache folder (files being written by another
run, the VM test's assets) is touched.
"""

from __future__ import annotations

import contextlib
import math
import os
from pathlib import Path

from ..errors import ConfigError

CACHE_MAX_ENV = "DEPTHTOUCH_CACHE_MAX_GB"
DEFAULT_MAX_GB = 50.0


def cache_limit_bytes() -> int | None:
    """The size limit of the recordings' folder in bytes (None: no limit), from the environment."""
    text = os.environ.get(CACHE_MAX_ENV)
    if text is None or not text.strip():
        return int(DEFAULT_MAX_GB * 1e9)
    try:
        gb = float(text)
    except ValueError:
        gb = math.nan
    if not (gb >= 0.0 and math.isfinite(gb)):
        raise ConfigError(f"{CACHE_MAX_ENV}={text!r} is not a size; give the cache's limit in GB, "
                          f"e.g. {CACHE_MAX_ENV}=50 (0: no limit)")
    return None if gb == 0.0 else int(gb * 1e9)


def mark_used(recording: Path) -> None:
    """Set a cached recording's modification time to now (its last use)."""
    # a read-only cache is still read, its recordings only not kept longer
    with contextlib.suppress(OSError):
        os.utime(recording)


def _truth_of(recording: Path) -> Path:
    return recording.with_suffix(".truth.json")


def prune(folder: Path, limit_bytes: int, keep: Path | None = None) -> list[Path]:
    """Delete the least recently used recordings (each ``.npz`` with its ``.truth.json``) of
    ``folder`` until the recordings there take at most ``limit_bytes``; ``keep`` is never
    deleted, nor are files being written (``*.part*``). Returns the deleted recordings, oldest
    first."""
    entries: list[tuple[float, int, Path]] = []
    total = 0
    for rec in folder.glob("*.npz"):
        if ".part" in rec.name:
            continue
        try:
            st = rec.stat()
            truth = _truth_of(rec)
            size = st.st_size + (truth.stat().st_size if truth.is_file() else 0)
        except OSError:  # deleted by another run meanwhile
            continue
        total += size
        entries.append((st.st_mtime, size, rec))
    deleted: list[Path] = []
    for _, size, rec in sorted(entries, key=lambda e: (e[0], e[2].name)):
        if total <= limit_bytes:
            break
        if keep is not None and rec == keep:
            continue
        rec.unlink(missing_ok=True)
        _truth_of(rec).unlink(missing_ok=True)
        total -= size
        deleted.append(rec)
    return deleted
