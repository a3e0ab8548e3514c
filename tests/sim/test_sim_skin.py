"""The simulator's amplitude-dependent noise (``render_scene(skin_noise=...)``): the temporal
noise of what stands on the surface times the factor, and every pixel's noise growing as 1/cos
of its incidence angle; nothing else changes (no random draw, no bias, no edge artefact)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from depthtouch.cli import main
from depthtouch.errors import ConfigError
from depthtouch.evaluation.suite import suite_from_dict
from depthtouch.sim import render_scene
from depthtouch.sim.cameras import NoiseModel, get_profile

KW = {"camera": "kinect-v2", "distance_m": 1.0, "seed": 3}


def _std(static: np.ndarray, frame: np.ndarray, skin: float, n: int = 300) -> np.ndarray:
    """Per-pixel temporal std (mm) of ``frame`` over n frames, ``static`` the surface."""
    model = NoiseModel(get_profile("kinect-v2"), np.random.default_rng(5), skin)
    model.set_static(static)
    h, w = static.shape
    out = np.stack([model.apply(frame, (0, 0, w, h)).astype(np.float64) for _ in range(n)])
    return out.std(axis=0)


def test_what_stands_on_the_surface_is_noisier_by_the_factor() -> None:
    """A box 100 mm in front of a plane facing the camera at 1 m: with skin_noise 2 its noise is
    twice the surface's (the 1/12 mm² of rounding aside), the plane's stays as it was."""
    h, w = get_profile("kinect-v2").resolution_wh[::-1]
    static = np.full((h, w), 1000.0, np.float32)
    frame = static.copy()
    frame[150:250, 200:300] = 900.0
    box, plane = (slice(155, 245), slice(205, 295)), (slice(20, 120), slice(20, 120))
    one, two = _std(static, frame, 1.0), _std(static, frame, 2.0)
    ratio_box = np.median(two[box]) / np.median(one[box])
    assert 1.85 < ratio_box < 2.1
    assert abs(np.median(two[plane]) / np.median(one[plane]) - 1.0) < 0.03


def test_a_surface_turned_away_is_noisier_as_one_over_the_cosine() -> None:
    """A plane whose depth grows by tan(30 deg) mm per mm across the view reads 1/cos(30 deg)
    = 1.15 times noisier with the option (any factor above 1 turns it on)."""
    p = get_profile("kinect-v2")
    w, h = p.resolution_wh
    rows = np.arange(h, dtype=np.float32)[:, None]
    # at 1 m, one pixel is 1000 / f mm wide: depth rising tan(30 deg) per mm across it
    static = np.broadcast_to(1000.0 + (rows - h / 2) * np.float32(np.tan(np.radians(30)) * 1000.0
                                                                / p.fx_px), (h, w))
    static = np.ascontiguousarray(static, dtype=np.float32)
    mid = (slice(h // 2 - 40, h // 2 + 40), slice(100, 400))
    one, on = _std(static, static, 1.0), _std(static, static, 1.5)
    assert abs(np.median(on[mid]) / np.median(one[mid]) - 1.0 / np.cos(np.radians(30))) < 0.04


def test_no_skin_noise_leaves_the_recording_as_it_was() -> None:
    a = render_scene("taps", fps=4.0, **KW)
    b = render_scene("taps", fps=4.0, skin_noise=1.0, **KW)
    c = render_scene("taps", fps=4.0, skin_noise=1.5, **KW)
    assert np.array_equal(a.depth, b.depth)
    assert a.truth == c.truth
    empty = a.truth["empty_frames"]  # a plane facing the camera: its noise is unchanged
    assert empty > 0 and np.array_equal(a.depth[:empty], c.depth[:empty])
    assert not np.array_equal(a.depth, c.depth)


@pytest.mark.parametrize("k", [0.5, 4.5, "2"])
def test_skin_noise_out_of_range_is_refused_with_the_range(k: object) -> None:
    with pytest.raises(ConfigError, match=r"skin_noise .* is out of range; allowed \[1, 4\]"):
        render_scene("taps", fps=4.0, skin_noise=k, **KW)  # type: ignore[arg-type]


def test_a_suite_group_sets_the_skin_noise_and_names_it() -> None:
    group = {"name": "g", "scenes": ["taps"], "cameras": ["kinect-v2-hard"],
             "distances_m": [1.0], "seeds": [1]}
    (case,) = suite_from_dict({"group": [{**group, "skin_noise": 1.5}]}).cases
    assert case.skin_noise == 1.5 and "/skin1.5/" in case.label
    assert case.render_kwargs()["skin_noise"] == 1.5
    (plain,) = suite_from_dict({"group": [group]}).cases
    assert "skin_noise" not in plain.render_kwargs() and "/skin" not in plain.label
    assert plain.cache_key() != case.cache_key()
    with pytest.raises(ConfigError, match=r"skin_noise value 5.0 is out of range"):
        suite_from_dict({"group": [{**group, "skin_noise": 5.0}]})


def test_sim_cli_takes_skin_noise_and_refuses_it_with_views(tmp_path: Path, capsys) -> None:
    out, truth = tmp_path / "s.npz", tmp_path / "s.json"
    assert main(["sim", "taps", "--camera", "kinect-v2", "--fps", "4", "--skin-noise", "1.5",
                 "--out", str(out), "--truth", str(truth), "-q"]) == 0
    assert out.is_file() and truth.is_file()
    assert main(["sim", "taps", "--views", "2", "--skin-noise", "1.5", "--out",
                 str(tmp_path / "v"), "--truth", str(tmp_path / "v.json")]) == 2
    assert "--skin-noise applies to one camera" in capsys.readouterr().err
