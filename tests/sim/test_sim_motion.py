"""Time-of-flight motion mixing (``render_scene(motion_ms=...)``, ``depthtouch sim --motion-ms``,
a suite group's ``motion_ms``): each frame is the mean of renders at 4 instants over the last
``motion_ms``, so the pixels a moving hand sweeps read depths between hand and surface."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from depthtouch.cli import main
from depthtouch.errors import ConfigError
from depthtouch.evaluation.suite import suite_from_dict
from depthtouch.sim import render_scene
from depthtouch.sim.artefacts import exposure_mix

KW = {"camera": "kinect-v2", "distance_m": 1.0, "seed": 3, "resolution_scale": 0.5}


def test_exposure_mix_is_the_mean_where_every_render_sees_depth_inside_the_box() -> None:
    a = np.full((4, 5), 1000.0, np.float32)
    b = a.copy()
    b[1, 1:4] = 960.0  # a hand part that moved in
    b[2, 2] = 0.0  # no depth in one render: the frame's own value stays
    c = a.copy()
    c[1, 1] = 900.0
    keep = [z.copy() for z in (a, b, c)]
    out = exposure_mix([a, b, c], (1, 0, 3, 4))  # x 1..2, every row
    for z, k in zip((a, b, c), keep, strict=True):
        assert np.array_equal(z, k)  # inputs untouched
    assert out[1, 1] == pytest.approx((1000 + 960 + 900) / 3)
    assert out[1, 2] == pytest.approx((1000 + 960 + 1000) / 3)
    assert out[1, 3] == 1000.0  # outside the box: the frame's own
    assert out[2, 2] == 1000.0
    assert np.array_equal(exposure_mix([a], (0, 0, 5, 4)), a)
    assert np.array_equal(exposure_mix([a, b], (2, 2, 2, 4)), a)  # an empty box


def test_mixed_frames_are_the_mean_of_the_frames_over_the_span() -> None:
    """At 120 fps a 50 ms span centred on frame i puts the 4 instants on frames i-3, i-1, i+1
    and i+3: frame i with the mixing is the mean of those four frames without it (exact
    geometry, rounded to mm)."""
    plain = render_scene("drags", fps=120.0, noise=False, **KW).depth.astype(np.float64)
    mixed = render_scene("drags", fps=120.0, noise=False, motion_ms=50.0, **KW).depth
    n = plain.shape[0]
    stack = np.stack([plain[:n - 6], plain[2:n - 4], plain[4:n - 2], plain[6:]])
    seen = np.all(stack > 0, axis=0)
    want = np.where(seen, stack.mean(axis=0), stack[0])
    got = mixed[3:n - 3].astype(np.float64)
    assert np.abs(got - want).max() <= 2.0  # rounded to mm before the mean here, after it there
    moved = np.any(stack != stack[0], axis=0) & seen
    assert moved.sum() > 250  # the drags sweep pixels, and those are mixed
    assert np.abs(got[moved] - plain[3:n - 3][moved]).max() >= 5


def test_no_motion_leaves_the_recording_as_it_was_and_still_frames_unmixed() -> None:
    a = render_scene("taps", fps=10.0, **KW)
    b = render_scene("taps", fps=10.0, motion_ms=0.0, **KW)
    c = render_scene("taps", fps=10.0, motion_ms=13.0, **KW)
    assert np.array_equal(a.depth, b.depth)
    assert a.truth == c.truth  # the truth is the frame's own instant
    empty = a.truth["empty_frames"]
    assert empty > 0 and np.array_equal(a.depth[:empty], c.depth[:empty])
    assert not np.array_equal(a.depth, c.depth)


@pytest.mark.parametrize("ms", [-1.0, 51.0, "13"])
def test_motion_out_of_range_is_refused_with_the_range(ms: object) -> None:
    with pytest.raises(ConfigError, match=r"motion_ms .* is out of range; allowed \[0, 50\]"):
        render_scene("taps", fps=4.0, motion_ms=ms, **KW)  # type: ignore[arg-type]


def test_a_suite_group_sets_the_motion_and_names_it() -> None:
    group = {"name": "g", "scenes": ["taps"], "cameras": ["kinect-v2-hard"],
             "distances_m": [1.0], "seeds": [1]}
    s = suite_from_dict({"group": [{**group, "motion_ms": 13.0}]})
    (case,) = s.cases
    assert case.motion_ms == 13.0 and "/motion13/" in case.label
    assert case.render_kwargs()["motion_ms"] == 13.0
    (plain,) = suite_from_dict({"group": [group]}).cases
    assert "motion_ms" not in plain.render_kwargs() and "/motion" not in plain.label
    assert plain.cache_key() != case.cache_key()
    with pytest.raises(ConfigError, match=r"motion_ms value 60.0 is out of range"):
        suite_from_dict({"group": [{**group, "motion_ms": 60.0}]})


def test_sim_cli_takes_motion_and_refuses_it_with_views(tmp_path: Path, capsys) -> None:
    out, truth = tmp_path / "m.npz", tmp_path / "m.json"
    assert main(["sim", "taps", "--camera", "kinect-v2", "--fps", "4", "--motion-ms", "13",
                 "--out", str(out), "--truth", str(truth), "-q"]) == 0
    assert out.is_file() and truth.is_file()
    assert main(["sim", "taps", "--views", "2", "--motion-ms", "13", "--out",
                 str(tmp_path / "v"), "--truth", str(tmp_path / "v.json")]) == 2
    assert "--motion-ms applies to one camera" in capsys.readouterr().err
