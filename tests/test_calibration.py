"""Screen calibration: homography fit, round trips, files and the `calibrate` command."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from depthtouch.calibration import (
    Calibration,
    apply_calibration,
    default_targets,
    fit_calibration,
    load_calibration,
    load_point_pairs,
    parse_screen_wh,
    save_calibration,
)
from depthtouch.cli import main
from depthtouch.errors import CalibrationError
from depthtouch.types import TouchEvent

SCREEN = (1920, 1080)
# A plausible camera-to-screen mapping: ~3x scale, slight rotation, shear and perspective.
H_TRUE = np.array([
    [3.05, 0.12, -95.0],
    [-0.08, 2.95, -60.0],
    [1.2e-4, -0.9e-4, 1.0],
])


def project(H: np.ndarray, xy: np.ndarray) -> np.ndarray:
    p = np.c_[xy, np.ones(len(xy))] @ H.T
    return p[:, :2] / p[:, 2:]


def pairs_for(screen_xy: np.ndarray, noise_px: float, seed: int) -> np.ndarray:
    """Depth points of the given screen targets, with Gaussian touch noise in depth pixels."""
    rng = np.random.default_rng(seed)
    depth = project(np.linalg.inv(H_TRUE), screen_xy)
    return depth + rng.normal(0.0, noise_px, depth.shape)


GRID = np.stack(np.meshgrid(np.linspace(100, 1800, 7), np.linspace(80, 1000, 5)), -1).reshape(-1, 2)


@pytest.mark.parametrize(
    ("n_targets", "noise_px", "max_rms_px", "max_grid_err_px"),
    [
        (4, 0.0, 1e-3, 1e-2),  # exact: 4 pairs fix H
        (9, 0.0, 1e-3, 1e-2),
        (9, 0.3, 2.5, 3.0),  # 0.3 depth px ~ 0.9 screen px per point
        (25, 0.5, 3.0, 3.0),
    ],
)
def test_known_homography_is_recovered(n_targets, noise_px, max_rms_px, max_grid_err_px):
    screen = default_targets(SCREEN, n_targets)
    depth = pairs_for(screen, noise_px, seed=n_targets)
    cal = fit_calibration(depth, screen, SCREEN)
    assert cal.n_points == n_targets and cal.n_inliers == n_targets
    assert 0.0 <= cal.reprojection_error_px <= max_rms_px
    if noise_px > 0:
        assert cal.reprojection_error_px > 0.05  # noise shows in the reported error
        assert cal.max_error_px >= cal.reprojection_error_px
        # an untouched point is predicted worse than the fitted ones
        assert cal.reprojection_error_px < cal.loo_error_px < 4 * max_rms_px
    if n_targets < 8:
        assert np.isnan(cal.loo_error_px)  # too few pairs for an honest error estimate
    # the mapping over the whole screen, not only at the targets
    depth_grid = project(np.linalg.inv(H_TRUE), GRID)
    err = np.linalg.norm(cal.to_screen(depth_grid) - GRID, axis=1)
    assert err.max() <= max_grid_err_px


def test_ransac_rejects_a_bad_touch():
    screen = default_targets(SCREEN, 9)
    depth = pairs_for(screen, 0.2, seed=3)
    depth[4] += (40.0, -25.0)  # the user touched far from the centre target
    cal = fit_calibration(depth, screen, SCREEN)
    assert cal.n_inliers == 8
    assert cal.reprojection_error_px < 2.0
    depth_grid = project(np.linalg.inv(H_TRUE), GRID)
    assert np.abs(cal.to_screen(depth_grid) - GRID).max() < 3.0


def test_round_trip_screen_depth_screen_within_half_pixel():
    screen = default_targets(SCREEN, 9)
    cal = fit_calibration(pairs_for(screen, 0.4, seed=1), screen, SCREEN)
    rng = np.random.default_rng(2)
    sxy = rng.uniform((0, 0), SCREEN, (500, 2))
    back = cal.to_screen(cal.to_depth(sxy))
    assert np.abs(back - sxy).max() < 0.5
    # single points keep their shape; inputs are not modified
    p = np.array([960.0, 540.0])
    assert cal.to_depth(p).shape == (2,)
    assert np.allclose(cal.to_screen(cal.to_depth(p)), p, atol=0.5)
    assert np.allclose(cal.to_unit(cal.to_depth(p[None]))[0], (0.5, 0.5), atol=1e-3)


@settings(max_examples=60, deadline=None)
@given(
    sx=st.floats(0.5, 4.0), sy=st.floats(0.5, 4.0), rot=st.floats(-0.5, 0.5),
    tx=st.floats(-300, 300), ty=st.floats(-300, 300),
    px=st.floats(-3e-4, 3e-4), py=st.floats(-3e-4, 3e-4),
    noise_seed=st.integers(0, 2**16),
)
def test_property_homography_round_trip(sx, sy, rot, tx, ty, px, py, noise_seed):
    c, s = np.cos(rot), np.sin(rot)
    H = np.array([[sx * c, -sy * s, tx], [sx * s, sy * c, ty], [px, py, 1.0]])
    depth = np.array([[40, 30], [600, 40], [610, 450], [30, 440], [320, 240], [200, 350.0]])
    w = np.c_[depth, np.ones(6)] @ H.T
    if np.any(np.abs(w[:, 2]) < 0.2):
        return  # the horizon line crosses the image: not a camera looking at a screen
    screen = w[:, :2] / w[:, 2:]
    cal = fit_calibration(depth, screen, SCREEN)
    assert cal.reprojection_error_px < 1e-2
    rng = np.random.default_rng(noise_seed)
    q = rng.uniform((40, 30), (600, 440), (50, 2))
    assert np.abs(cal.to_depth(cal.to_screen(q)) - q).max() < 1e-3
    sq = cal.to_screen(q)
    assert np.abs(cal.to_screen(cal.to_depth(sq)) - sq).max() < 1e-2


CORNERS = default_targets(SCREEN, 4)
DEPTH4 = pairs_for(CORNERS, 0.0, 0)


@pytest.mark.parametrize(
    ("depth", "screen", "wh", "match"),
    [
        (DEPTH4[:3], CORNERS[:3], SCREEN, "too few"),
        (DEPTH4, CORNERS[:3], SCREEN, "one depth point per target"),
        (DEPTH4[:, :1], CORNERS, SCREEN, r"expected shape \(N, 2\)"),
        (np.where(np.eye(4, 2, dtype=bool), np.nan, DEPTH4), CORNERS, SCREEN, "NaN"),
        (np.c_[np.linspace(0, 100, 6), np.linspace(0, 50, 6)], default_targets(SCREEN, 9)[:6],
         SCREEN, "collinear"),
        (np.array([[0, 0], [10, 10], [20, 20.0], [5, 40]]), CORNERS, SCREEN, "on a line"),
        (np.repeat(DEPTH4[:1], 4, axis=0), CORNERS, SCREEN, "coincide"),
        (DEPTH4, CORNERS, (0, 1080), "screen_wh"),
        (DEPTH4, CORNERS, (1920.5, 1080), "screen_wh"),
        ("abc", CORNERS, SCREEN, "not numeric"),
    ],
)
def test_bad_point_sets_raise_one_line(depth, screen, wh, match):
    with pytest.raises(CalibrationError, match=match) as ei:
        fit_calibration(depth, screen, wh)
    assert "\n" not in str(ei.value)


def test_default_targets():
    t4 = default_targets((1000, 500), 4, margin=0.1)
    assert t4.shape == (4, 2)
    assert np.allclose(t4[0], (99.9, 49.9)) and np.allclose(t4[2], (899.1, 449.1))
    assert default_targets((1000, 500), 5)[4].tolist() == [499.5, 249.5]
    t9 = default_targets((1000, 500), 9)
    assert t9.shape == (9, 2) and len(np.unique(t9, axis=0)) == 9
    # serpentine: consecutive targets are neighbours
    assert np.all(np.linalg.norm(np.diff(t9, axis=0), axis=1) <= 450)
    for n, margin in [(3, 0.1), (6, 0.1), (4, 0.5), (4, -0.1)]:
        with pytest.raises(CalibrationError):
            default_targets((1000, 500), n, margin)


def test_save_load_round_trip(tmp_path: Path):
    screen = default_targets(SCREEN, 9)
    cal = fit_calibration(pairs_for(screen, 0.3, 5), screen, SCREEN)
    p = save_calibration(cal, tmp_path / "calib.json")
    assert [x.name for x in tmp_path.iterdir()] == ["calib.json"]  # no temporary left behind
    back = load_calibration(p)
    assert np.allclose(back.H, cal.H, rtol=0, atol=1e-12)
    assert back.screen_wh == SCREEN
    assert back.reprojection_error_px == pytest.approx(cal.reprojection_error_px)
    assert back.n_inliers == cal.n_inliers and back.depth_xy is not None
    assert back.loo_error_px == pytest.approx(cal.loo_error_px)
    assert json.loads(p.read_text())["format"] == "depthtouch-calibration"


def _valid() -> dict:
    return {"format": "depthtouch-calibration", "version": 1, "H": H_TRUE.tolist(),
            "screen_wh": [1920, 1080], "reprojection_error_px": 0.5}


@pytest.mark.parametrize(
    ("content", "match"),
    [
        (None, "does not exist"),
        ("{not json", "not valid JSON"),
        ("[1, 2]", "not a calibration object"),
        (json.dumps({**_valid(), "format": "other"}), "format"),
        (json.dumps({**_valid(), "version": 7}), "version 7"),
        (json.dumps({k: v for k, v in _valid().items() if k != "H"}), "missing key 'H'"),
        (json.dumps({**_valid(), "H": [[1, 0], [0, 1]]}), "3x3"),
        (json.dumps({**_valid(), "H": [[1, 0, 0], [0, 1, 0], [0, 0, "x"]]}), "not numbers"),
        (json.dumps({**_valid(), "H": [[1, 2, 0], [2, 4, 0], [0, 0, 0]]}), "singular"),
        (json.dumps({**_valid(), "screen_wh": [1920]}), "screen_wh"),
        (json.dumps({**_valid(), "screen_wh": 5}), "screen_wh"),
        (json.dumps({**_valid(), "reprojection_error_px": -1}), "must be >= 0"),
        (json.dumps({**_valid(), "depth_xy": [[1, 2]], "screen_xy": [[1, 2], [3, 4]]}), "differ"),
    ],
)
def test_bad_calibration_files_give_one_line_error(tmp_path: Path, content, match):
    p = tmp_path / "calib.json"
    if content is not None:
        p.write_text(content)
    with pytest.raises(CalibrationError, match=match) as ei:
        load_calibration(p)
    assert "\n" not in str(ei.value)


def test_valid_hand_written_file_loads(tmp_path: Path):
    p = tmp_path / "c.json"
    p.write_text(json.dumps(_valid()))
    cal = load_calibration(p)
    assert np.isnan(cal.max_error_px) and cal.depth_xy is None


def test_save_to_missing_folder_is_one_line(tmp_path: Path):
    cal = Calibration(H_TRUE, SCREEN, 0.0)
    with pytest.raises(CalibrationError, match="does not exist"):
        save_calibration(cal, tmp_path / "nope" / "c.json")
    with pytest.raises(CalibrationError, match="is a folder"):
        save_calibration(cal, tmp_path)


def test_apply_calibration_adds_sx_sy_without_mutating():
    cal = Calibration(H_TRUE, SCREEN, 0.0)
    evs = [TouchEvent(3, 0.1, 1, "down", 100.0, 200.0, {"area": 12}),
           TouchEvent(3, 0.1, 2, "move", 300.0, 50.0)]
    out = apply_calibration(evs, cal)
    want = project(H_TRUE, np.array([[100.0, 200.0], [300.0, 50.0]]))
    got = np.array([(e.extra["sx"], e.extra["sy"]) for e in out])
    assert np.allclose(got, want)
    assert all(type(e.extra["sx"]) is float for e in out)  # JSON- and OSC-safe, not numpy
    assert out[0].extra["area"] == 12
    assert "sx" not in evs[0].extra
    assert apply_calibration(evs, None) == evs


@pytest.mark.parametrize(
    ("text", "want"),
    [("1920x1080", (1920, 1080)), ("800X600", (800, 600)), ("1920", None), ("axb", None),
     ("0x10", None), ("-5x10", None)],
)
def test_parse_screen_wh(text, want):
    if want is None:
        with pytest.raises(CalibrationError):
            parse_screen_wh(text)
    else:
        assert parse_screen_wh(text) == want


def test_cli_calibrate_writes_file(tmp_path: Path, capsys):
    screen = default_targets(SCREEN, 5)
    depth = pairs_for(screen, 0.2, 9)
    pairs = {"pairs": [{"depth_xy": d.tolist(), "screen_xy": s.tolist()}
                       for d, s in zip(depth, screen, strict=True)]}
    (tmp_path / "pairs.json").write_text(json.dumps(pairs))
    out = tmp_path / "calib.json"
    rc = main(["calibrate", "--points", str(tmp_path / "pairs.json"), "--screen", "1920x1080",
               "--out", str(out)])
    assert rc == 0
    cal = load_calibration(out)
    assert cal.n_points == 5 and cal.reprojection_error_px < 2.0
    assert "reprojection error" in capsys.readouterr().out
    rows4 = [[*d, *s] for d, s in zip(DEPTH4.tolist(), CORNERS.tolist(), strict=True)]
    (tmp_path / "four.json").write_text(json.dumps(rows4))
    assert main(["calibrate", "--points", str(tmp_path / "four.json"), "--screen", "1920x1080",
                 "--out", str(tmp_path / "c4.json")]) == 0
    assert "use 5 or more targets" in capsys.readouterr().out
    # the bare-rows form, and screen_wh taken from the file
    rows = [[*d, *s] for d, s in zip(depth.tolist(), screen.tolist(), strict=True)]
    (tmp_path / "rows.json").write_text(json.dumps(rows))
    d2, s2, wh = load_point_pairs(tmp_path / "rows.json")
    assert np.allclose(d2, depth) and wh is None
    (tmp_path / "p2.json").write_text(json.dumps({**pairs, "screen_wh": [1920, 1080]}))
    assert main(["calibrate", "--points", str(tmp_path / "p2.json"), "--out",
                 str(tmp_path / "c2.json")]) == 0


@pytest.mark.parametrize(
    ("content", "args", "match"),
    [
        ('{"pairs": [{"depth_xy": [1, 2]}]}', ["--screen", "1920x1080"], "screen_xy"),
        ("[[1, 2, 3]]", ["--screen", "1920x1080"], "rows of"),
        ('{"pairs": []}', ["--screen", "1920x1080"], "no point pairs"),
        (json.dumps([[*d, *s] for d, s in zip(DEPTH4.tolist(), CORNERS.tolist(), strict=True)]),
         [], "screen size unknown"),
        ("{oops", ["--screen", "1920x1080"], "not valid JSON"),
        ('{"pairs": [{"depth_xy": [0,0], "screen_xy": [0,0]}]}', ["--screen", "10"],
         "WIDTHxHEIGHT"),
        ('[[0,0,0,0],[1,1,1,1],[2,2,2,2],[3,3,3,3]]', ["--screen", "1920x1080"], "collinear"),
    ],
)
def test_cli_calibrate_errors_exit_2_with_one_line(tmp_path: Path, capsys, content, args, match):
    (tmp_path / "pairs.json").write_text(content)
    rc = main(["calibrate", "--points", str(tmp_path / "pairs.json"), *args, "--out",
               str(tmp_path / "c.json")])
    err = capsys.readouterr().err
    assert rc == 2
    assert err.count("\n") == 1 and match in err
    assert not (tmp_path / "c.json").exists()
