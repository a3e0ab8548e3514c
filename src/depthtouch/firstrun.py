"""The first run after installing compiles the numba kernels (~20 s on 2 cores): say so.

:func:`warm_up` runs the kernels' warm-up steps; when the on-disk cache is cold it first writes
one line to stderr ("compiling the touch kernels once, ~20 s; cached in ...") and keeps it up to
date with the steps done (on a terminal), so that the silent pause does not look like a hang.
A warm cache (every later run, ~1.5 s to load) prints nothing.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, TextIO

ESTIMATE_S = 20


def cache_state(kernels: Sequence[Any]) -> tuple[bool, Path | None]:
    """(cold, cache folder) for numba dispatchers compiled with ``cache=True``.

    Cold when a kernel has no index file in its cache folder (``NUMBA_CACHE_DIR`` or the
    package's ``__pycache__``). Reads numba's cache locator; if that changes in a later numba,
    the answer is "warm" (no message), never an error.
    """
    folder: Path | None = None
    try:
        for k in kernels:
            cache = k._cache  # numba FunctionCache
            folder = Path(cache.cache_path)
            if not Path(cache._cache_file._index_path).exists():
                return True, folder
    except (AttributeError, TypeError):
        return False, folder
    return False, folder


def warm_up(steps: Sequence[Callable[[], None]], kernels: Sequence[Any],
            stream: TextIO | None = None) -> float | None:
    """Run ``steps``; with a cold cache, tell ``stream`` (default stderr) what happens.

    Returns the seconds the steps took when the cache was cold, else None.
    """
    cold, folder = cache_state(kernels)
    if not cold:
        for step in steps:
            step()
        return None
    out = stream if stream is not None else sys.stderr
    tty = bool(getattr(out, "isatty", lambda: False)())
    where = folder if folder is not None else "numba's cache"
    line = f"depthtouch: compiling the touch kernels once, ~{ESTIMATE_S} s; cached in {where}"
    t0 = time.monotonic()
    print(line + (f" [0/{len(steps)}]" if tty else ""), end="" if tty else "\n", file=out,
          flush=True)
    for i, step in enumerate(steps, 1):
        step()
        if tty:
            print(f"\r{line} [{i}/{len(steps)}]", end="", file=out, flush=True)
    took = time.monotonic() - t0
    print(f"{chr(13) + line if tty else 'depthtouch: kernels compiled'} ({took:.0f} s)", file=out,
          flush=True)
    return took
