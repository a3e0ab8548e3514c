"""How far a suite half's figures would move with other recordings: bootstrap intervals.

A half holds 25-50 recordings, and some measures rest on a few of them: on the hard suite's
tune half, one recording of 50 holds 23 % of the squared still-finger jitter and three hold
44 % (docs/accuracy.md, section 7, session 36). A change that moves such a figure by less than
its spread over recordings cannot be told from the luck of the draw, and an unseen set of
recordings (the maintainers') lands anywhere within it.

:func:`bootstrap_intervals` resamples a half's recordings with replacement (the recording is
the unit: its contacts share a hand, a noise draw and a placement), recomputes the figures of
:func:`depthtouch.evaluation.halves.figures` on each resample, and gives each measure of
:data:`CI_KEYS` the central interval of the resampled values (percentile bootstrap). Seeded, so
a report is reproducible.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Sequence
from typing import Any

import numpy as np

from ..errors import ConfigError
from .metrics import EvalResult

#: the measures given an interval (those a few recordings can move; counts are left out)
CI_KEYS = ("recall_working", "false_per_min", "error_median_mm", "error_p95_mm",
           "jitter_rms_mm", "angle_error_deg", "recall_drift")
#: the measures a comparison of two configurations gives (with the counts an issue bounds)
COMPARE_KEYS = (*CI_KEYS, "false_touches", "false_from_hover_25mm", "early_from_hover_25mm",
                "id_switches")
#: resamples allowed by ``depthtouch eval --ci``
CI_MIN, CI_MAX = 100, 100_000


def check_resamples(n: int) -> int:
    """``n`` if it is a usable number of resamples, else a :class:`ConfigError` naming the
    range."""
    if not CI_MIN <= n <= CI_MAX:
        raise ConfigError(f"--ci {n} is out of range; give {CI_MIN}-{CI_MAX} resamples "
                          f"(1000 is plenty for 95 % intervals)")
    return n


def _resampled(
    sets: Sequence[Sequence[EvalResult]],
    figures_of: Callable[[list[EvalResult], list[bool], list[bool]], dict[str, Any]],
    far: Sequence[bool],
    drift: Sequence[bool],
    resamples: int,
    seed: int,
) -> Iterator[list[dict[str, Any]]]:
    """For each of ``resamples`` draws of the recordings with replacement (seeded), the figures
    of every result set in ``sets`` on that draw (the sets hold the same recordings, in the
    same order; ``far`` and ``drift`` are per recording and travel with it)."""
    n = len(sets[0])
    rng = np.random.default_rng(seed)
    for _ in range(resamples if n else 0):
        pick = rng.integers(0, n, n).tolist()
        sub_far, sub_drift = [far[i] for i in pick], [drift[i] for i in pick]
        yield [figures_of([rs[i] for i in pick], sub_far, sub_drift) for rs in sets]


def _finite(v: Any) -> bool:
    return v is not None and math.isfinite(v)


def bootstrap_intervals(
    results: Sequence[EvalResult],
    figures_of: Callable[[list[EvalResult], list[bool], list[bool]], dict[str, Any]],
    far: Sequence[bool],
    drift: Sequence[bool],
    *,
    resamples: int = 1000,
    level: float = 0.95,
    seed: int = 0,
) -> dict[str, list[float] | None]:
    """The ``level`` percentile-bootstrap interval of each measure of :data:`CI_KEYS`.

    ``figures_of(results, far, drift)`` computes the figures (``halves.figures``); ``far`` and
    ``drift`` are per result and travel with it. A measure gets ``[lo, hi]``, or None when
    fewer than half of the resamples define it (a half without drift recordings has no recall
    under drift). Pure: the same inputs and seed give the same intervals.
    """
    draws: dict[str, list[float]] = {k: [] for k in CI_KEYS}
    for (f,) in _resampled([results], figures_of, far, drift, resamples, seed):
        for k in CI_KEYS:
            if _finite(f.get(k)):
                draws[k].append(float(f[k]))
    return {k: _interval(draws[k], resamples, level) for k in CI_KEYS}


def _interval(draws: list[float], resamples: int, level: float) -> list[float] | None:
    """The central ``level`` interval of the resampled values, or None when fewer than half of
    the resamples gave one."""
    if len(draws) * 2 < resamples:
        return None
    tail = 100.0 * (1.0 - level) / 2.0
    lo, hi = np.percentile(np.asarray(draws), [tail, 100.0 - tail])
    return [round(float(lo), 4), round(float(hi), 4)]


def paired_intervals(
    results_a: Sequence[EvalResult],
    results_b: Sequence[EvalResult],
    figures_of: Callable[[list[EvalResult], list[bool], list[bool]], dict[str, Any]],
    far: Sequence[bool],
    drift: Sequence[bool],
    *,
    resamples: int = 1000,
    level: float = 0.95,
    seed: int = 0,
) -> dict[str, dict[str, Any]]:
    """Two configurations run on the same recordings: for each measure of :data:`COMPARE_KEYS`,
    ``{"a": figure, "b": figure, "diff": b - a, "ci": [lo, hi] | None}``.

    Each resample draws the recordings once and computes both figures on them, so what the
    draw adds to both cancels: the interval of b - a is much narrower than either figure's own
    (:func:`bootstrap_intervals`) when the change moves few recordings. An interval that holds
    0 is a change the recordings cannot tell from none. ``results_a[i]`` and ``results_b[i]``
    must be the same recording.
    """
    n = len(results_a)
    if len(results_b) != n:
        raise ValueError(f"paired results differ in length: {n} against {len(results_b)}")
    fa, fb = figures_of(list(results_a), list(far), list(drift)), figures_of(
        list(results_b), list(far), list(drift))
    draws: dict[str, list[float]] = {k: [] for k in COMPARE_KEYS}
    for ra, rb in _resampled([results_a, results_b], figures_of, far, drift, resamples, seed):
        for k in COMPARE_KEYS:
            if _finite(ra.get(k)) and _finite(rb.get(k)):
                draws[k].append(float(rb[k]) - float(ra[k]))
    out: dict[str, dict[str, Any]] = {}
    for k in COMPARE_KEYS:
        a, b = fa.get(k), fb.get(k)
        diff = None if a is None or b is None else round(float(b) - float(a), 4)
        ci = None if diff is None else _interval(draws[k], resamples, level)
        out[k] = {"a": a, "b": b, "diff": diff, "ci": ci}
    return out
