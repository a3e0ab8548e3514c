"""`depthtouch replay` on bad input: exit code 2, one line on stderr naming the problem and the
fix, no traceback, and no events file (complete or partial) left behind.

Every row of the table builds its bad input in a fresh folder and returns the replay arguments;
the needle is a piece of the message that names the problem (or the allowed range).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import zipfile
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np
import pytest

from conftest import CliResult, leftovers
from depthtouch.outputs.jsonl import read_events
from depthtouch.sources import write_png_folder
from depthtouch.surface.model import learn_surface
from synth import K_640, make_recording, write_recording

Arrays = tuple[np.ndarray, np.ndarray]
Builder = Callable[[Path, Arrays], list[object]]


def _npz(path: Path, **arrays: object) -> Path:
    np.savez(path, **arrays)  # type: ignore[arg-type]
    return path


def _text(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def _rec(tmp: Path, a: Arrays, **over: object) -> list[object]:
    """A recording with some of its arrays replaced (None removes the key)."""
    depth, ts = a
    arrays: dict[str, object] = {"depth": depth, "timestamps": ts, "depth_scale": 0.001,
                                 "K": K_640}
    arrays.update(over)
    return [_npz(tmp / "bad.npz", **{k: v for k, v in arrays.items() if v is not None})]


def _ts_with(a: Arrays, i: int, value: float) -> np.ndarray:
    ts = a[1].copy()
    ts[i] = value
    return ts


def _text_as_npz(tmp: Path, a: Arrays) -> list[object]:
    (tmp / "notes.npz").write_text("this is not a recording\n")
    return [tmp / "notes.npz"]


def _zip_without_depth(tmp: Path, a: Arrays) -> list[object]:
    with zipfile.ZipFile(tmp / "other.npz", "w") as z:
        z.writestr("image.npy", b"\x93NUMPY nothing useful")
    return [tmp / "other.npz"]


def _npy_as_npz(tmp: Path, a: Arrays) -> list[object]:
    with (tmp / "bare.npz").open("wb") as fh:
        np.save(fh, a[0])
    return [tmp / "bare.npz"]


def _damaged_npz(tmp: Path, a: Arrays) -> list[object]:
    p = write_recording(tmp / "damaged.npz", *a)
    data = bytearray(p.read_bytes())
    data[len(data) // 3] ^= 0xFF  # inside the compressed depth member
    p.write_bytes(bytes(data))
    return [p]


def _png(tmp: Path, a: Arrays) -> Path:
    return write_png_folder(tmp / "png", a[0], a[1], 0.001, K_640)


def _png_meta(tmp: Path, a: Arrays, text: str | None) -> list[object]:
    root = _png(tmp, a)
    if text is None:
        (root / "meta.json").unlink()
    else:
        (root / "meta.json").write_text(text)
    return [root]


def _png_frame(tmp: Path, a: Arrays, i: int, image: np.ndarray | bytes) -> list[object]:
    root = _png(tmp, a)
    target = root / "depth" / f"{i:06d}.png"
    if isinstance(image, bytes):
        target.write_bytes(image)
    else:
        assert cv2.imwrite(str(target), image)
    return [root]


def _png_timestamps(tmp: Path, a: Arrays, text: str | None) -> list[object]:
    root = _png(tmp, a)
    if text is None:
        (root / "timestamps.txt").unlink()
        (root / "meta.json").write_text(json.dumps({"depth_scale": 0.001}))
    else:
        (root / "timestamps.txt").write_text(text)
    return [root]


def _empty_png_folder(tmp: Path, a: Arrays) -> list[object]:
    root = tmp / "png"
    (root / "depth").mkdir(parents=True)
    (root / "meta.json").write_text(json.dumps({"depth_scale": 0.001, "fps": 30}))
    return [root]


def _surface(tmp: Path, a: Arrays, kind: str) -> list[object]:
    rec = write_recording(tmp / "rec.npz", *a)
    target = tmp / "surface.npz"
    if kind == "garbage":
        target.write_bytes(np.random.default_rng(3).bytes(500))
    elif kind == "text":
        target.write_text("surface = flat\n")
    elif kind == "recording":
        target = rec
    elif kind == "missing":
        target = tmp / "nothing.npz"
    elif kind == "other-resolution":
        depth, _ = make_recording(4, [], shape=(30, 40), seed=1)
        learn_surface(depth, 0.001, K_640).save(target)
    return [rec, "--surface", target]


def _config(tmp: Path, a: Arrays, text: str | bytes | None) -> list[object]:
    rec = write_recording(tmp / "rec.npz", *a)
    cfg = tmp / "config.toml"
    if isinstance(text, bytes):
        cfg.write_bytes(text)
    elif text is not None:
        cfg.write_text(text)
    return [rec, "--config", cfg]


def _with(*extra: object) -> Builder:
    def build(tmp: Path, a: Arrays) -> list[object]:
        return [write_recording(tmp / "rec.npz", *a), *extra]

    return build


def _events_to(where: str) -> Builder:
    def build(tmp: Path, a: Arrays) -> list[object]:
        target = tmp / "no-such-folder" / "ev.jsonl" if where == "missing-folder" else tmp
        return [write_recording(tmp / "rec.npz", *a), "--events", target]

    return build


def _save_surface_to(where: str) -> Builder:
    def build(tmp: Path, a: Arrays) -> list[object]:
        target = tmp / "no-such-folder" / "s.npz" if where == "missing-folder" else tmp
        return [write_recording(tmp / "rec.npz", *a), "--save-surface", target]

    return build


CASES: list[tuple[str, Builder, str]] = [
    # --- the recording file ------------------------------------------------------------------
    ("missing file", lambda t, a: [t / "nope.npz"], "no such file"),
    ("unknown extension", lambda t, a: [_text(t / "rec.csv", "0,1,2\n")],
     "unknown recording type"),
    ("text file named .npz", _text_as_npz, "not a readable .npz"),
    ("zip without depth", _zip_without_depth, "no 'depth' array"),
    ("bare .npy named .npz", _npy_as_npz, "not an .npz archive"),
    ("damaged compressed data", _damaged_npz, "the depth data is damaged"),
    ("float32 depth", lambda t, a: _rec(t, a, depth=a[0].astype(np.float32)), "dtype float32"),
    ("2-D depth", lambda t, a: _rec(t, a, depth=a[0][0]), "expected (N, H, W)"),
    ("0 frames", lambda t, a: _rec(t, a, depth=a[0][:0], timestamps=a[1][:0]), "no frames"),
    ("tiny frames", lambda t, a: _rec(t, a, depth=a[0][:, :4, :4]), "too small"),
    ("10 frames at 30 fps", lambda t, a: _rec(t, a, depth=a[0][:10], timestamps=a[1][:10]),
     "shorter than the 1.5 s"),
    ("no timestamps", lambda t, a: _rec(t, a, timestamps=None), "no 'timestamps'"),
    ("timestamps count", lambda t, a: _rec(t, a, timestamps=a[1][:-1]), "for 65 frames"),
    ("timestamps text", lambda t, a: _rec(t, a, timestamps=np.array(["x"] * len(a[1]))),
     "not numbers"),
    ("repeated timestamp", lambda t, a: _rec(t, a, timestamps=_ts_with(a, 5, a[1][4])),
     "not strictly increasing"),
    ("decreasing timestamp", lambda t, a: _rec(t, a, timestamps=_ts_with(a, 9, 0.0)),
     "not strictly increasing"),
    ("NaN timestamp", lambda t, a: _rec(t, a, timestamps=_ts_with(a, 3, np.nan)), "NaN"),
    ("inf timestamp", lambda t, a: _rec(t, a, timestamps=_ts_with(a, 3, np.inf)), "NaN or inf"),
    ("no depth_scale", lambda t, a: _rec(t, a, depth_scale=None), "no 'depth_scale'"),
    ("depth_scale 0", lambda t, a: _rec(t, a, depth_scale=0.0), "[1e-6, 1]"),
    ("depth_scale negative", lambda t, a: _rec(t, a, depth_scale=-0.001), "[1e-6, 1]"),
    ("depth_scale NaN", lambda t, a: _rec(t, a, depth_scale=np.nan), "[1e-6, 1]"),
    ("depth_scale 5.0", lambda t, a: _rec(t, a, depth_scale=5.0), "[1e-6, 1]"),
    ("depth_scale text", lambda t, a: _rec(t, a, depth_scale="mm"), "not a number"),
    ("depth_scale array", lambda t, a: _rec(t, a, depth_scale=np.zeros((2, 2))),
     "shape (2, 2)"),
    ("K 2x2", lambda t, a: _rec(t, a, K=np.eye(2)), "3x3"),
    ("K zeros", lambda t, a: _rec(t, a, K=np.zeros((3, 3))), "positive fx, fy"),
    ("K NaN", lambda t, a: _rec(t, a, K=np.full((3, 3), np.nan)), "finite 3x3"),
    ("K negative fx", lambda t, a: _rec(t, a, K=-K_640), "positive fx, fy"),
    ("K text", lambda t, a: _rec(t, a, K=np.array([["a"] * 3] * 3)), "K is not numeric"),
    # --- PNG folders ---------------------------------------------------------------------------
    ("PNG folder without meta.json", lambda t, a: _png_meta(t, a, None), "no meta.json"),
    ("meta.json not JSON", lambda t, a: _png_meta(t, a, "{depth_scale: 1"), "not valid JSON"),
    ("meta.json a list", lambda t, a: _png_meta(t, a, "[0.001, 30]"), "JSON object"),
    ("meta.json no depth_scale", lambda t, a: _png_meta(t, a, '{"fps": 30}'), "no depth_scale"),
    ("meta.json depth_scale true", lambda t, a: _png_meta(t, a, '{"depth_scale": true}'),
     "not a number"),
    ("meta.json K ragged", lambda t, a: _png_meta(t, a, '{"depth_scale": 0.001, "K": [[1], 2]}'),
     "K is not numeric"),
    ("8-bit PNG", lambda t, a: _png_frame(t, a, 0, (a[0][0] // 256).astype(np.uint8)),
     "16-bit single-channel"),
    ("colour PNG", lambda t, a: _png_frame(t, a, 0, np.dstack([a[0][0]] * 3)),
     "16-bit single-channel"),
    ("random bytes as PNG", lambda t, a: _png_frame(t, a, 0, b"\x89PNG garbage" * 9),
     "not a readable PNG"),
    ("frames of different sizes", lambda t, a: _png_frame(t, a, 3, a[0][3][:40]),
     "all frames must have one size"),
    ("empty PNG folder", _empty_png_folder, "no frames"),
    ("timestamps.txt bad line", lambda t, a: _png_timestamps(t, a, "0.0\nzero\n"),
     "timestamps.txt:2"),
    ("timestamps.txt too short", lambda t, a: _png_timestamps(t, a, "0.0\n0.1\n"),
     "for 65 frames"),
    ("no fps and no timestamps.txt", lambda t, a: _png_timestamps(t, a, None), "fps"),
    # --- outputs -------------------------------------------------------------------------------
    ("events folder missing", _events_to("missing-folder"), "does not exist"),
    ("events path is a folder", _events_to("folder"), "is a folder"),
    ("save-surface folder missing", _save_surface_to("missing-folder"), "does not exist"),
    ("save-surface path is a folder", _save_surface_to("folder"), "is a folder"),
    # --- surface files -------------------------------------------------------------------------
    ("surface garbage", lambda t, a: _surface(t, a, "garbage"), "not a depthtouch surface"),
    ("surface text", lambda t, a: _surface(t, a, "text"), "not a depthtouch surface"),
    ("surface is a recording", lambda t, a: _surface(t, a, "recording"),
     "not a depthtouch surface"),
    ("surface missing", lambda t, a: _surface(t, a, "missing"), "no such surface file"),
    ("surface of another resolution", lambda t, a: _surface(t, a, "other-resolution"),
     "40x30 but the recording is 80x60"),
    # --- config files --------------------------------------------------------------------------
    ("config missing", lambda t, a: _config(t, a, None), "does not exist"),
    ("config syntax error", lambda t, a: _config(t, a, "[surface\nlearn_s = 1"),
     "not valid TOML"),
    ("config not UTF-8", lambda t, a: _config(t, a, b"\xff\xfe[surface]"), "UTF-8"),
    ("config unknown section", lambda t, a: _config(t, a, "[surfaces]\nlearn_s = 1.0"),
     "unknown config section [surfaces]"),
    ("config unknown key", lambda t, a: _config(t, a, "[regions]\ntu = 20"),
     "unknown key regions.tu"),
    ("config wrong type", lambda t, a: _config(t, a, "[regions]\ntu_mm = 'high'"),
     "must be a number"),
    ("config float for int", lambda t, a: _config(t, a, "[tracking]\ndown_frames = 2.5"),
     "must be a whole number"),
    ("config out of range", lambda t, a: _config(t, a, "[surface]\nlearn_s = 100.0"),
     "allowed (0.0, 60.0]"),
    ("config int out of range", lambda t, a: _config(t, a, "[tracking]\nup_frames = 0"),
     "allowed [1, 30]"),
    ("config huge int", lambda t, a: _config(t, a, "[regions]\ntu_mm = 1" + "0" * 400),
     "allowed (0.0, 200.0]"),
    ("config NaN", lambda t, a: _config(t, a, "[regions]\nnoise_k = nan"), "allowed [0.0, 20.0]"),
    ("config learn_frames", lambda t, a: _config(t, a, "[surface]\nlearn_frames = 1"),
     "allowed [2, 10000]"),
    ("config unknown statistic", lambda t, a: _config(t, a, "[surface]\nstatistic = 'max'"),
     "use mean, mode or median"),
    ("config section not a table", lambda t, a: _config(t, a, "surface = 3"), "must be a table"),
    ("config filter param text", lambda t, a: _config(t, a, "[filter.params]\nbeta = 'x'"),
     "must be a number"),
    ("config unknown filter", lambda t, a: _config(t, a, "[filter]\nname = 'magic'"),
     "unknown filter 'magic'"),
    # --- options -------------------------------------------------------------------------------
    ("--surface-frames 1", _with("--surface-frames", 1), "at least 2"),
    ("--surface-frames 0", _with("--surface-frames", 0), "at least 2"),
    ("--surface-frames > frames", _with("--surface-frames", 100), "fewer than the 100"),
    ("--surface-frames not a number", _with("--surface-frames", "ten"), "invalid int value"),
    ("--filter unknown", _with("--filter", "magic"), "unknown filter 'magic'"),
    ("--calibration missing", lambda t, a: [*_with()(t, a), "--calibration", t / "c.json"],
     "does not exist"),
    ("--calibration not JSON", lambda t, a: [*_with()(t, a), "--calibration",
                                             *_text_as_npz(t, a)], "not valid JSON"),
    ("--tuio bad port", _with("--tuio", "localhost:99999"), "[1, 65535]"),
]


@pytest.mark.parametrize(("name", "build", "needle"), CASES, ids=[c[0] for c in CASES])
def test_replay_bad_input_is_one_line_exit_2(
    name: str, build: Builder, needle: str, tmp_path: Path, small_arrays: Arrays,
    cli: Callable[..., CliResult],
) -> None:
    args = build(tmp_path, small_arrays)
    events = tmp_path / "events.jsonl"
    if "--events" not in args:
        args += ["--events", events]
    r = cli("replay", *args, "-q")
    assert r.rc == 2, r
    assert len(r.err_lines) == 1, r.err
    assert r.err.startswith("depthtouch: error: ")
    assert "Traceback" not in r.err
    assert needle in r.err, r.err
    assert r.out == ""
    assert not events.exists()
    assert leftovers(tmp_path) == []


def _png_size_change_after_learning(tmp: Path, a: Arrays) -> Path:
    root = _png(tmp, a)
    assert cv2.imwrite(str(root / "depth" / f"{len(a[1]) - 3:06d}.png"), a[0][-3][:40])
    return root


def _png_8bit_after_learning(tmp: Path, a: Arrays) -> Path:
    root = _png(tmp, a)
    assert cv2.imwrite(str(root / "depth" / f"{len(a[1]) - 5:06d}.png"),
                       (a[0][-5] // 256).astype(np.uint8))
    return root


@pytest.mark.parametrize("build", [_png_size_change_after_learning, _png_8bit_after_learning])
def test_failure_mid_run_keeps_no_events_and_leaves_an_old_file_alone(
    build: Callable[[Path, Arrays], Path], tmp_path: Path, small_arrays: Arrays,
    cli: Callable[..., CliResult],
) -> None:
    root = build(tmp_path, small_arrays)
    out = tmp_path / "out"
    out.mkdir()
    fresh, old = out / "fresh.jsonl", out / "old.jsonl"
    old.write_text("previous run\n")
    for target in (fresh, old):
        r = cli("replay", root, "--events", target, "-q")
        assert r.rc == 2 and len(r.err_lines) == 1 and "Traceback" not in r.err, r
    assert not fresh.exists()
    assert old.read_text() == "previous run\n"
    assert leftovers(out) == []


def test_success_writes_a_complete_events_file(
    npz_recording: Path, tmp_path: Path, cli: Callable[..., CliResult]
) -> None:
    events = tmp_path / "out.jsonl"
    surface = tmp_path / "surface.npz"
    r = cli("replay", npz_recording, "--events", events, "--save-surface", surface)
    assert r.rc == 0, r.err
    assert "1 touches" in r.out and f"wrote {events}" in r.out
    text = events.read_text()
    assert text.endswith("\n")
    evs = list(read_events(events))
    n_events = int(r.out.split(" events")[0].rsplit(" ", 1)[-1])
    assert len(evs) == n_events == len(text.splitlines()) > 0
    states = [e.state for e in evs]
    assert states[0] == "down" and states[-1] == "up" and set(states[1:-1]) == {"move"}
    assert [e.frame for e in evs] == sorted(e.frame for e in evs)
    assert leftovers(tmp_path) == []
    # the saved surface replaces learning: same touch, no error
    r2 = cli("replay", npz_recording, "--surface", surface, "--events", tmp_path / "b.jsonl", "-q")
    assert r2.rc == 0, r2.err
    assert [e.state for e in read_events(tmp_path / "b.jsonl")][0] == "down"


def test_png_folder_and_npz_give_the_same_events(
    npz_recording: Path, png_recording: Path, tmp_path: Path, cli: Callable[..., CliResult]
) -> None:
    a, b = tmp_path / "a.jsonl", tmp_path / "b.jsonl"
    assert cli("replay", npz_recording, "--events", a, "-q").rc == 0
    assert cli("replay", png_recording, "--events", b, "-q").rc == 0
    assert a.read_text() == b.read_text() != ""


def test_recording_without_valid_depth_says_so_in_one_line(tmp_path: Path) -> None:
    """All-zero depth: the surface cannot be learned. Run as a real process, so that a logging
    warning printed by Python's last-resort handler counts as a second stderr line."""
    depth = np.zeros((60, 24, 32), np.uint16)
    rec = write_recording(tmp_path / "zeros.npz", depth, np.arange(60) / 30.0)
    env = {**os.environ, "PYTHONWARNINGS": "ignore"}
    p = subprocess.run([sys.executable, "-m", "depthtouch.cli", "replay", str(rec), "-q"],
                       capture_output=True, text=True, env=env, timeout=120, check=False)
    assert p.returncode == 2
    assert len(p.stderr.splitlines()) == 1, p.stderr
    assert "valid depth" in p.stderr


@pytest.mark.parametrize("option", ["--events", "--save-surface"])
def test_outputs_never_overwrite_the_recording(
    option: str, npz_recording: Path, cli: Callable[..., CliResult]
) -> None:
    before = npz_recording.read_bytes()
    r = cli("replay", npz_recording, option, npz_recording, "-q")
    assert npz_recording.read_bytes() == before
    assert r.rc == 2 and len(r.err_lines) == 1 and "Traceback" not in r.err
    assert "is the recording itself" in r.err


@pytest.mark.parametrize(
    "args, needle",
    [
        (["replay", "rec.npz", "--out", "x"], "unrecognized arguments: --out x (see depthtouch replay -h)"),
        (["--bogus"], "unrecognized arguments: --bogus (see depthtouch -h)"),
        (["replay"], "required: recording (see depthtouch replay -h)"),
        (["eval", "--half", "nope"], "invalid choice: 'nope'"),
    ],
)
def test_usage_errors_name_the_command_whose_help_to_read(
    cli: Callable[..., CliResult], args: list[str], needle: str
) -> None:
    r = cli(*args)
    assert r.rc == 2 and len(r.err_lines) == 1 and needle in r.err, r
    assert "depthtouch depthtouch" not in r.err
