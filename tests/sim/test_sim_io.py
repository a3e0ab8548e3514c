"""Simulator I/O: the sim: source, writing recordings + truth, load_truth validation, the CLI."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from depthtouch.cli import main
from depthtouch.errors import SourceError
from depthtouch.sim import load_truth, render_scene, write_recording
from depthtouch.sources import NpzSource, PngFolderSource, open_source
from depthtouch.types import Frame


@pytest.fixture(scope="module")
def small_rec() -> Any:
    return render_scene("taps", camera="kinect-v2", seed=1, fps=6)


def test_open_source_sim_yields_frames() -> None:
    src = open_source("sim:taps", camera="kinect-v1", fps=5, seed=2)
    with src:
        frames = list(src.frames())
    assert src.resolution_wh == (640, 480) and src.fps == 5.0
    assert len(frames) == len(src)  # type: ignore[arg-type]
    assert all(isinstance(f, Frame) for f in frames)
    assert [f.index for f in frames] == list(range(len(frames)))
    assert frames[0].timestamp_s == 0.0 and frames[1].timestamp_s == pytest.approx(0.2)
    assert frames[0].K is not None and frames[0].K[0, 0] == 580.0
    assert frames[0].depth.dtype == np.uint16 and frames[0].depth_scale_m == 0.001
    assert src.truth["scene"] == "taps"  # type: ignore[attr-defined]


@pytest.mark.parametrize(
    ("spec", "options", "message"),
    [
        ("sim:tapz", {}, "unknown simulator scene 'tapz'; use sim:NAME with NAME one of taps"),
        ("sim:taps", {"colour": 1}, "unknown option(s) colour; allowed camera"),
        ("sim:taps", {"distance_m": 9.0}, "sim:taps: distance 9.0 m is out of range"),
        ("sim:taps", {"camera": "x"}, "unknown camera 'x'"),
    ],
)
def test_open_source_sim_errors(spec: str, options: dict[str, Any], message: str) -> None:
    with pytest.raises(SourceError) as err:
        open_source(spec, **options)
    assert message in str(err.value) and "\n" not in str(err.value)


def test_write_npz_and_truth_round_trip(tmp_path: Path, small_rec: Any) -> None:
    write_recording(small_rec, tmp_path / "taps.npz", tmp_path / "taps.truth.json")
    src = NpzSource(tmp_path / "taps.npz")
    assert np.array_equal(src.read_all(), small_rec.depth)
    assert src.K is not None
    np.testing.assert_allclose(src.K, small_rec.K)
    truth = load_truth(tmp_path / "taps.truth.json")
    assert truth == json.loads(json.dumps(small_rec.truth))
    assert truth["format"] == "depthtouch-truth/1"
    assert truth["camera"]["resolution_wh"] == [512, 424]
    assert len(truth["frames"]) == small_rec.depth.shape[0]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["taps.npz", "taps.truth.json"]


def test_write_png_folder(tmp_path: Path, small_rec: Any) -> None:
    write_recording(small_rec, tmp_path / "rec", tmp_path / "rec.truth.json")
    src = PngFolderSource(tmp_path / "rec")
    frames = list(src.frames())
    assert len(frames) == small_rec.depth.shape[0]
    assert np.array_equal(frames[3].depth, small_rec.depth[3])
    assert src.fps == pytest.approx(6.0)


@pytest.mark.parametrize(
    ("out", "truth", "message"),
    [
        ("missing/x.npz", "x.truth.json", "does not exist; create it first"),
        ("x.npz", "missing/x.truth.json", "does not exist; create it first"),
        ("x.avi", "x.truth.json", "unknown recording type '.avi'"),
        ("x.npz", "x.truth.txt", "must end in .json"),
        ("same.json", "same.json", "need different paths"),
        ("full_dir", "x.truth.json", "exists and is not an empty folder"),
    ],
)
def test_write_recording_errors(tmp_path: Path, small_rec: Any, out: str, truth: str,
                                message: str) -> None:
    (tmp_path / "full_dir").mkdir()
    (tmp_path / "full_dir" / "keep.txt").write_text("x", encoding="utf-8")
    with pytest.raises(SourceError) as err:
        write_recording(small_rec, tmp_path / out, tmp_path / truth)
    assert message in str(err.value) and "\n" not in str(err.value)
    # nothing was written: no recording, no truth, no temporary files
    assert sorted(p.name for p in tmp_path.iterdir()) == ["full_dir"]


def _valid_truth() -> dict[str, Any]:
    return {
        "format": "depthtouch-truth/1", "scene": "taps", "seed": 0,
        "camera": {"profile": "kinect-v2", "resolution_wh": [512, 424],
                   "K": [[365.5, 0, 256], [0, 365.5, 208], [0, 0, 1]], "depth_scale": 0.001,
                   "fps": 30},
        "surface": {"kind": "plane"}, "empty_frames": 1,
        "frames": [
            {"frame": 0, "t": 0.0, "contacts": [], "hovers": []},
            {"frame": 1, "t": 0.033, "contacts": [
                {"id": 1, "x": 1.0, "y": 2.0, "X": 0.0, "Y": 1.0, "Z": 900.0, "nx": 0.0,
                 "ny": 0.0, "nz": -1.0}],
             "hovers": [{"id": 2, "x": 1.0, "y": 2.0, "X": 0.0, "Y": 1.0, "Z": 900.0,
                         "height_mm": 25.0}]},
        ],
        "events": [{"kind": "bump", "frame": 1}],
    }


def _broken(change: str) -> dict[str, Any]:
    d = _valid_truth()
    if change == "format":
        d["format"] = "other/2"
    elif change == "no_frames":
        del d["frames"]
    elif change == "K":
        d["camera"]["K"] = [[1, 0], [0, 1]]
    elif change == "frame_index":
        d["frames"][1]["frame"] = 5
    elif change == "contact_field":
        del d["frames"][1]["contacts"][0]["nz"]
    elif change == "hover_height":
        d["frames"][1]["hovers"][0]["height_mm"] = "high"
    elif change == "events":
        d["events"] = [{"frame": 1}]
    return d


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ("format", "format is 'other/2', expected 'depthtouch-truth/1'"),
        ("no_frames", "missing key 'frames'"),
        ("K", "camera.K must be a 3x3 matrix"),
        ("frame_index", "frames[1] needs frame = 1"),
        ("contact_field", "frames[1].contacts entries need numbers id, x, y"),
        ("hover_height", "frames[1].hovers entries need numbers"),
        ("events", "events must be a list of {kind, frame}"),
    ],
)
def test_load_truth_rejects_bad_files(tmp_path: Path, change: str, message: str) -> None:
    p = tmp_path / "t.json"
    p.write_text(json.dumps(_broken(change)), encoding="utf-8")
    with pytest.raises(SourceError) as err:
        load_truth(p)
    assert message in str(err.value) and "\n" not in str(err.value)


def test_load_truth_valid_and_unreadable(tmp_path: Path) -> None:
    p = tmp_path / "t.json"
    p.write_text(json.dumps(_valid_truth()), encoding="utf-8")
    assert load_truth(p)["frames"][1]["contacts"][0]["id"] == 1
    p.write_text("{not json", encoding="utf-8")
    with pytest.raises(SourceError, match="not valid JSON"):
        load_truth(p)
    with pytest.raises(SourceError, match="no such truth file"):
        load_truth(tmp_path / "nope.json")


def test_cli_sim(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out, truth = tmp_path / "h.npz", tmp_path / "h.truth.json"
    rc = main(["sim", "hold", "--out", str(out), "--truth", str(truth), "--camera", "kinect-v1",
               "--distance", "1.2", "--tilt", "10", "--surface", "cylinder-convex", "--seed",
               "3", "--fps", "4"])
    assert rc == 0
    assert "1 contacts" in capsys.readouterr().out
    t = load_truth(truth)
    assert t["surface"]["kind"] == "cylinder-convex" and t["surface"]["tilt_deg"] == 10.0
    assert t["seed"] == 3 and t["camera"]["profile"] == "kinect-v1"
    assert NpzSource(out).resolution_wh == (640, 480)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["nope"], "unknown scene 'nope'"),
        (["taps", "--distance", "3"], "distance 3.0 m is out of range; allowed [0.5, 2.5] m"),
        (["taps", "--surface", "cone"], "unknown surface 'cone'"),
    ],
)
def test_cli_sim_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str],
                        message: str) -> None:
    rc = main(["sim", *args, "--out", str(tmp_path / "x.npz"), "--truth",
               str(tmp_path / "x.json"), "--fps", "2"])
    assert rc == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1
    assert not list(tmp_path.iterdir())
