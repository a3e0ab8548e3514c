"""Output files written once: a path that can be written, and writes that are all or nothing.

An output is written to a temporary file beside its target and renamed into place only when
complete, so that a run that fails (or a full disk, or Ctrl-C in the middle of a one-shot write)
never leaves a half-written file behind and never damages the previous one.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import IO

from .errors import DepthTouchError, OutputError


def check_output_path(path: str | Path, *, what: str = "the output",
                      error: type[DepthTouchError] = OutputError) -> Path:
    """``path`` as a Path, or ``error``: it is a folder, or its folder does not exist."""
    p = Path(path)
    parent = p.parent if str(p.parent) else Path(".")
    if p.is_dir():
        raise error(f"{p}: is a folder; give a file name for {what}")
    if not parent.is_dir():
        raise error(f"{p}: folder {parent} does not exist; create it first")
    return p


def temp_beside(path: Path, *, suffix: str = ".part", folder: bool = False,
                error: type[DepthTouchError] = OutputError) -> Path:
    """A new, empty temporary file (or folder) in ``path``'s folder, named after it."""
    parent = path.parent if str(path.parent) else Path(".")
    try:
        if folder:
            return Path(tempfile.mkdtemp(prefix=f".{path.name}.", suffix=suffix, dir=parent))
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=suffix, dir=parent)
        os.close(fd)
        return Path(tmp)
    except OSError as e:
        raise error(f"{path}: cannot write here ({e.strerror}); choose another path") from e


def discard(tmp: Path) -> None:
    """Remove a temporary file or folder (nothing if it is gone)."""
    if tmp.is_dir():
        shutil.rmtree(tmp, ignore_errors=True)
    else:
        tmp.unlink(missing_ok=True)


@contextlib.contextmanager
def atomic_path(path: str | Path, *, suffix: str = ".part", folder: bool = False,
                what: str = "the output", error: type[DepthTouchError] = OutputError
                ) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on a clean exit it replaces ``path``, on any
    error it is removed. An OSError while writing becomes ``error`` naming the path."""
    p = check_output_path(path, what=what, error=error)
    tmp = temp_beside(p, suffix=suffix, folder=folder, error=error)
    try:
        yield tmp
        if folder and p.is_dir():
            shutil.rmtree(p)
        os.replace(tmp, p)
    except OSError as e:
        discard(tmp)
        raise error(f"{p}: cannot write ({e.strerror or e}); choose another path") from e
    except BaseException:
        discard(tmp)
        raise


def write_text_atomic(path: str | Path, text: str, *, what: str = "the output",
                      error: type[DepthTouchError] = OutputError) -> Path:
    """Write ``text`` (UTF-8) to ``path`` all or nothing; returns the path."""
    with atomic_path(path, what=what, error=error) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return Path(path)


class AtomicTextFile:
    """A text file written line by line into a temporary file; :meth:`close` with
    ``commit=True`` moves it into place, otherwise it is removed."""

    def __init__(self, path: str | Path, *, what: str = "the output",
                 error: type[DepthTouchError] = OutputError) -> None:
        self.path = check_output_path(path, what=what, error=error)
        self._tmp = temp_beside(self.path, error=error)
        self.fh: IO[str] | None = self._tmp.open("w", encoding="utf-8")

    def close(self, commit: bool = True) -> None:
        fh, self.fh = self.fh, None
        if fh is None:
            return
        fh.close()
        if commit:
            os.replace(self._tmp, self.path)
        else:
            self._tmp.unlink(missing_ok=True)
