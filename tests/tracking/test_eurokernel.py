"""The ``adaptive_euro`` filter's compiled step against its array version (the oracle).

Both run on the same streams: several touches that come and go, rest, jump by one frame, drag,
turn and stop, with noise from 0.5 to 5 mm and frame intervals that vary by ±20 %. Outputs agree
to 1e-9 mm (the sums' order differs), and every discrete state (landing, lock, restart) is the
same frame by frame.
"""

from __future__ import annotations

import numpy as np
import pytest

from depthtouch.tracking.adaptive_euro import AdaptiveEuroFilter


class ArrayEuro(AdaptiveEuroFilter):
    """The filter with its numpy step (the oracle)."""

    def _step(self, s: np.ndarray, xy: np.ndarray, dt_s: np.ndarray) -> np.ndarray:
        return self._step_arrays(s, xy, dt_s)


def _stream(seed: int, n: int = 500, k: int = 4) -> list[tuple[np.ndarray, np.ndarray, float]]:
    rng = np.random.default_rng(seed)
    pos = rng.uniform(0, 300, (k, 2))
    vel = np.zeros((k, 2))
    alive = np.ones(k, bool)
    t, out = 0.0, []
    for _ in range(n):
        t += rng.uniform(0.8, 1.2) / 30
        for i in range(k):
            r = rng.random()
            if r < 0.02:
                vel[i] = rng.normal(0, 300, 2)
            elif r < 0.05:
                vel[i] = 0
            if rng.random() < 0.01:
                alive[i] = not alive[i]
        pos += vel / 30
        xy = pos[alive] + rng.normal(0, rng.choice([0.5, 2.0, 5.0]), (int(alive.sum()), 2))
        if rng.random() < 0.05 and len(xy):
            xy[0] += 15.0  # a one-frame jump of a tip estimate
        out.append((np.flatnonzero(alive) + 10, xy, t))
    return out


def _slant_then_hold(seed: int) -> list[tuple[np.ndarray, np.ndarray, float]]:
    """A finger reported down while it still slides in (6 mm over 16 frames, 2 mm noise), then
    holds: the landing restarts from the held frames (as in test_filters.py)."""
    true = np.full((48, 2), 100.0)
    true[:16, 0] = 100.0 - np.linspace(6.0, 0.0, 16)
    xy = true + np.random.default_rng(seed).normal(0, 2.0, (48, 2))
    return [(np.array([1]), xy[f : f + 1], f / 30) for f in range(48)]


def _flags(f: AdaptiveEuroFilter, ids: np.ndarray) -> np.ndarray:
    rows = [f._rows[int(i)] for i in ids]
    return np.stack([f._buf[rows, f._COLS[k]][:, 0] for k in ("land", "ls", "n", "mv")], axis=1)


def _compare(params: dict[str, float], streams: list) -> dict[str, int]:
    """Runs both versions on the streams; returns how often each discrete state was seen."""
    seen = {"landing": 0, "locked": 0, "restarted": 0}
    for frames in streams:
        a, b = AdaptiveEuroFilter(**params), ArrayEuro(**params)
        for ids, xy, t in frames:
            np.testing.assert_allclose(a.update(ids, xy, t), b.update(ids, xy, t),
                                       rtol=0, atol=1e-9)
            fa = _flags(a, ids)
            np.testing.assert_array_equal(fa, _flags(b, ids))
            seen["landing"] += int((fa[:, 0] > 0).sum())
            seen["restarted"] += int((fa[:, 1] > 0).sum())
            seen["locked"] += int((fa[:, 2] > 0).sum())
    return seen


@pytest.mark.parametrize("params", [
    {}, {"reland_frames": 6}, {"land_frames": 0}, {"lock_frames": 0}, {"land_restart_frames": 0},
    {"lock_frames": 0, "land_frames": 0}, {"lock_mean_frames": 5, "lock_mm": 1.0},
    {"still_p": 0.01}, {"still_p": 0.2, "still_gate": 0.0, "still_q_mm2_s": 5.0},
    {"lock_frames": 0, "land_frames": 0, "still_p": 0.01},
    {"still_p": 0.01, "move_q_mm2_s3": 1e4, "still_noise_mm": 4.0, "still_noise_mul": 1.0},
    {"lock_resume_frames": 10}, {"lock_resume_frames": 10, "lock_mm": 1.0, "lock_sigmas": 1.0},
])
def test_compiled_step_is_the_array_step(params: dict[str, float]) -> None:
    seen = _compare(params, [_stream(s) for s in range(3)])
    if params.get("land_frames", 1) > 0:
        assert seen["landing"] > 50
    if params.get("lock_frames", 1) > 0:
        assert seen["locked"] > 50


def test_restart_and_relanding_match() -> None:
    seen = _compare({"lock_frames": 0}, [_slant_then_hold(s) for s in range(8)])
    assert seen["restarted"] > 30  # the landing restarted
    seen = _compare({"reland_frames": 6}, [_stream(s) for s in range(3, 5)])
    assert seen["restarted"] > 50  # touches landed again after moves


def test_still_finger_is_held() -> None:
    """A still finger's output moves far less than its measurements (the compiled path)."""
    rng = np.random.default_rng(7)
    f = AdaptiveEuroFilter()
    out = np.array([f.update(np.array([3]), (np.array([50.0, 60.0]) + rng.normal(0, 2.0, 2))[None],
                             k / 30)[0] for k in range(90)])
    assert np.sqrt(((out[40:] - out[40:].mean(axis=0)) ** 2).sum(axis=1).mean()) < 0.3
