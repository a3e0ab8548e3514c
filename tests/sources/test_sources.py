"""Depth sources: `open_source` dispatch, npz and PNG-folder round trips, writer and validator
errors."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from conftest import leftovers
from depthtouch.errors import DepthTouchError, SourceError
from depthtouch.sources import (
    NpzSource,
    PngFolderSource,
    open_source,
    write_npz,
    write_png_folder,
)
from depthtouch.sources.base import validate_depth_scale, validate_K, validate_timestamps
from synth import K_640


def _arrays(n: int = 6, shape: tuple[int, int] = (12, 16), seed: int = 0) -> tuple[np.ndarray,
                                                                                    np.ndarray]:
    rng = np.random.default_rng(seed)
    depth = rng.integers(0, 65536, size=(n, *shape), dtype=np.uint16)  # the full uint16 range
    depth[:, 0, 0] = 0
    depth[:, 0, 1] = 65535
    ts = 12.5 + np.cumsum(rng.uniform(0.01, 0.05, n))  # irregular, not a multiple of 1/fps
    return depth, ts


# --- dispatch ------------------------------------------------------------------------------------
def test_open_source_dispatches_by_path(tmp_path: Path) -> None:
    depth, ts = _arrays()
    write_npz(tmp_path / "a.npz", depth, ts)
    write_png_folder(tmp_path / "b", depth, ts)
    with open_source(tmp_path / "a.npz") as s:
        assert isinstance(s, NpzSource)
    with open_source(str(tmp_path / "b")) as s:
        assert isinstance(s, PngFolderSource)
    write_npz(tmp_path / "C.NPZ", depth, ts)  # the suffix is case-insensitive
    with open_source(tmp_path / "C.NPZ") as s:
        assert isinstance(s, NpzSource) and s.name == str(tmp_path / "C.NPZ")


@pytest.mark.parametrize(
    ("make", "needle"),
    [
        (lambda d: d / "missing.npz", "no such file"),
        (lambda d: d / "missing_folder", "no such file or folder"),
        (lambda d: d / "missing.png", "no such file or folder"),
        (lambda d: _touch(d / "notes.txt"), "unknown recording type '.txt'"),
        (lambda d: _touch(d / "README"), "(no extension)"),
        (lambda d: _mkdir(d / "rec.npz"), "no meta.json"),  # a folder wins over the suffix
        (lambda d: _touch(d / "rec.npz"), "not a readable .npz recording"),
    ],
    ids=["missing npz", "missing folder", "missing other", "unknown extension", "no extension",
         "folder named .npz", "empty npz"],
)
def test_open_source_errors(make: Callable[[Path], Path], needle: str, tmp_path: Path) -> None:
    with pytest.raises(SourceError) as e:
        open_source(make(tmp_path))
    assert needle in str(e.value)
    assert "\n" not in str(e.value)


def _touch(p: Path) -> Path:
    p.write_bytes(b"")
    return p


def _mkdir(p: Path) -> Path:
    p.mkdir()
    return p


# --- round trips ---------------------------------------------------------------------------------
@pytest.mark.parametrize("kind", ["npz", "png"])
@pytest.mark.parametrize("K", [K_640, None], ids=["K", "noK"])
@pytest.mark.parametrize("scale", [0.001, 0.000125, 1.0])
def test_written_recordings_read_back_bit_exact(
    kind: str, K: np.ndarray | None, scale: float, tmp_path: Path
) -> None:
    depth, ts = _arrays(seed=int(scale * 1e6) % 97)
    if kind == "npz":
        path = write_npz(tmp_path / "r.npz", depth, ts, scale, K)
    else:
        path = write_png_folder(tmp_path / "r", depth, ts, scale, K)
    with open_source(path) as src:
        assert src.depth_scale_m == scale
        assert src.resolution_wh == (16, 12)
        assert len(src) == 6  # type: ignore[arg-type]
        if K is None:
            assert src.K is None
        else:
            assert src.K is not None and src.K.dtype == np.float64
            np.testing.assert_array_equal(src.K, K)
        assert src.fps == pytest.approx(1.0 / np.median(np.diff(ts)))
        for _ in range(2):  # a recording can be iterated again
            frames = list(src.frames())
            assert [f.index for f in frames] == list(range(6))
            np.testing.assert_array_equal(np.array([f.timestamp_s for f in frames]), ts)
            got = np.stack([f.depth for f in frames])
            assert got.dtype == np.uint16
            np.testing.assert_array_equal(got, depth)
            assert all(f.depth_scale_m == scale for f in frames)
    assert leftovers(tmp_path) == []


def test_png_folder_without_timestamps_uses_fps(tmp_path: Path) -> None:
    depth, ts = _arrays(n=4)
    root = write_png_folder(tmp_path / "r", depth, ts, fps=25.0)
    (root / "timestamps.txt").unlink()
    assert json.loads((root / "meta.json").read_text())["fps"] == 25.0
    with PngFolderSource(root) as src:
        np.testing.assert_allclose([f.timestamp_s for f in src], np.arange(4) / 25.0)
        assert src.fps == pytest.approx(25.0)


def test_write_png_folder_into_an_empty_existing_folder(tmp_path: Path) -> None:
    depth, ts = _arrays(n=2)
    (tmp_path / "r").mkdir()
    write_png_folder(tmp_path / "r", depth, ts)
    assert len(PngFolderSource(tmp_path / "r")) == 2


def test_write_png_folder_into_a_non_empty_folder_fails_cleanly(tmp_path: Path) -> None:
    depth, ts = _arrays(n=2)
    target = tmp_path / "r"
    target.mkdir()
    (target / "keep.txt").write_text("mine")
    with pytest.raises(SourceError, match="not an empty folder"):
        write_png_folder(target, depth, ts)
    assert sorted(p.name for p in target.iterdir()) == ["keep.txt"]
    assert (target / "keep.txt").read_text() == "mine"
    (tmp_path / "file").write_text("x")
    with pytest.raises(SourceError, match="not an empty folder"):
        write_png_folder(tmp_path / "file", depth, ts)
    assert leftovers(tmp_path) == []


def test_write_npz_replaces_an_existing_file_atomically(tmp_path: Path) -> None:
    a, ta = _arrays(n=3, seed=1)
    b, tb = _arrays(n=5, seed=2)
    write_npz(tmp_path / "r.npz", a, ta)
    write_npz(tmp_path / "r.npz", b, tb)
    src = NpzSource(tmp_path / "r.npz")
    np.testing.assert_array_equal(src.read_all(), b)
    assert leftovers(tmp_path) == []


GOOD = _arrays(n=3)


@pytest.mark.parametrize(
    ("kwargs", "needle"),
    [
        ({"depth": GOOD[0].astype(np.int32)}, "uint16 (N, H, W)"),
        ({"depth": GOOD[0][0]}, "uint16 (N, H, W)"),
        ({"depth": GOOD[0][:0], "timestamps_s": GOOD[1][:0]}, "N >= 1"),
        ({"timestamps_s": GOOD[1][:2]}, "for 3 frames"),
        ({"timestamps_s": GOOD[1][::-1]}, "not strictly increasing"),
        ({"timestamps_s": np.array([0.0, np.nan, 1.0])}, "NaN"),
        ({"depth_scale_m": 0.0}, "[1e-6, 1]"),
        ({"depth_scale_m": float("nan")}, "[1e-6, 1]"),
        ({"K": np.eye(2)}, "3x3"),
        ({"K": np.zeros((3, 3))}, "positive fx, fy"),
    ],
    ids=["int32", "2-D", "no frames", "short timestamps", "reversed", "NaN time", "scale 0",
         "scale NaN", "K 2x2", "K zeros"],
)
@pytest.mark.parametrize("kind", ["npz", "png"])
def test_writers_refuse_what_the_readers_would_reject(
    kind: str, kwargs: dict[str, object], needle: str, tmp_path: Path
) -> None:
    args: dict[str, object] = {"depth": GOOD[0], "timestamps_s": GOOD[1], **kwargs}
    target = tmp_path / ("r.npz" if kind == "npz" else "r")
    with pytest.raises(SourceError) as e:
        if kind == "npz":
            write_npz(target, **args)  # type: ignore[arg-type]
        else:
            write_png_folder(target, **args)  # type: ignore[arg-type]
    assert needle in str(e.value)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("kind", ["npz", "png"])
def test_writers_name_a_missing_parent_folder(kind: str, tmp_path: Path) -> None:
    depth, ts = GOOD
    target = tmp_path / "nope" / ("r.npz" if kind == "npz" else "r")
    with pytest.raises(SourceError, match="does not exist"):
        if kind == "npz":
            write_npz(target, depth, ts)
        else:
            write_png_folder(target, depth, ts)
    assert list(tmp_path.iterdir()) == []


def test_write_npz_to_a_folder_fails_cleanly(tmp_path: Path) -> None:
    (tmp_path / "r.npz").mkdir()
    with pytest.raises(SourceError, match="is a folder"):
        write_npz(tmp_path / "r.npz", *GOOD)
    assert leftovers(tmp_path) == []


# --- validators ----------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("value", "expect"),
    [
        (0.001, 0.001),
        (1, 1.0),
        (np.float32(0.5), 0.5),
        (np.array(0.001), 0.001),
        (np.array([0.002]), 0.002),
        (1e-6, 1e-6),
        (0.0, "out of range"),
        (-0.001, "out of range"),
        (1.5, "out of range"),
        (float("inf"), "out of range"),
        (float("nan"), "out of range"),
        (True, "not a number"),
        ("0.001", "not a number"),
        (None, "not a number"),
        ([0.001], "not a number"),
        (np.array([0.001, 0.002]), "shape (2,)"),
        (np.array(["a"]), "not a number"),
        (np.array(1 + 0j), "not a number"),
    ],
)
def test_validate_depth_scale(value: object, expect: float | str) -> None:
    if isinstance(expect, str):
        with pytest.raises(SourceError) as e:
            validate_depth_scale(value, "rec")
        assert expect in str(e.value) and str(e.value).startswith("rec: ")
        assert "\n" not in str(e.value)
    else:
        assert validate_depth_scale(value, "rec") == expect


@pytest.mark.parametrize(
    ("value", "ok"),
    [
        (None, True),
        (K_640, True),
        (K_640.tolist(), True),
        (K_640.astype(np.float32), True),
        (np.eye(3, dtype=np.int64), True),
        (np.eye(3, dtype=bool), False),
        (np.eye(4), False),
        ([[1, 2], [3]], False),
        ({"fx": 600}, False),
        ("K", False),
        (np.full((3, 3), np.inf), False),
        (np.diag([600.0, -600.0, 1.0]), False),
        (np.array([[600, 0, 1], [0, 600, 1], [0, 0, 1]], dtype=complex), False),
    ],
)
def test_validate_K(value: object, ok: bool) -> None:
    if ok:
        K = validate_K(value, "rec")
        assert (K is None) == (value is None)
        if K is not None:
            assert K.dtype == np.float64 and K.shape == (3, 3)
    else:
        with pytest.raises(SourceError, match="^rec: K"):
            validate_K(value, "rec")


@pytest.mark.parametrize(
    ("value", "n", "needle"),
    [
        ([0.0, 0.1, 0.2], 3, None),
        (np.array([[0.0], [0.1]]), 2, None),
        (np.arange(3, dtype=np.int32), 3, None),
        ([5.0], 1, None),
        ([0.0, 0.1], 3, "2 timestamps"),
        ([0.0, 0.0], 2, "not strictly increasing"),
        ([0.2, 0.1], 2, "not strictly increasing"),
        ([0.0, float("nan")], 2, "NaN"),
        ([0.0, float("-inf")], 2, "NaN or inf"),
        (["a", "b"], 2, "not numbers"),
        ([[0.0, 1.0], [2.0]], 2, "not numbers"),
        ([True, False], 2, "not numbers"),
    ],
)
def test_validate_timestamps(value: object, n: int, needle: str | None) -> None:
    if needle is None:
        t = validate_timestamps(value, n, "rec")
        assert t.dtype == np.float64 and t.shape == (n,)
    else:
        with pytest.raises(DepthTouchError) as e:
            validate_timestamps(value, n, "rec")
        assert isinstance(e.value, SourceError) and needle in str(e.value)
