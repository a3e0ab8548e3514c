"""Surface files: save/load round trip, `with_statistic`, and one-line errors for bad files."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from conftest import leftovers
from depthtouch.errors import SurfaceError
from depthtouch.surface.model import SURFACE_FORMAT, SurfaceModel, learn_surface, load_surface
from synth import K_640, make_recording

STATS = ("mean", "mode", "median")


@pytest.fixture(scope="module")
def model() -> SurfaceModel:
    depth, _ = make_recording(12, [], shape=(24, 32), noise_mm=2.0, dropout=0.2, seed=5)
    return learn_surface(depth, 0.001, K_640)


def _same(a: SurfaceModel, b: SurfaceModel) -> None:
    for name in ("depth_mm", "mean_mm", "mode_mm", "median_mm", "sigma_mm", "valid"):
        x, y = getattr(a, name), getattr(b, name)
        assert x.dtype == y.dtype and x.shape == y.shape, name
        np.testing.assert_array_equal(x, y, err_msg=name)
    assert (a.statistic, a.depth_scale_m, a.n_frames) == (b.statistic, b.depth_scale_m, b.n_frames)
    if a.K is None:
        assert b.K is None
    else:
        assert b.K is not None
        np.testing.assert_array_equal(a.K, b.K)


@pytest.mark.parametrize("statistic", STATS)
@pytest.mark.parametrize("with_K", [True, False])
def test_save_load_round_trip(model: SurfaceModel, statistic: str, with_K: bool,
                              tmp_path: Path) -> None:
    m = model.with_statistic(statistic)
    if not with_K:
        m = SurfaceModel(m.depth_mm, m.mean_mm, m.mode_mm, m.median_mm, m.sigma_mm, m.valid,
                         m.statistic, 0.000125, None, m.n_frames)
    path = m.save(tmp_path / "s.npz")
    assert path == tmp_path / "s.npz"
    _same(m, load_surface(path))
    m.save(path)  # overwriting works and stays atomic
    _same(m, load_surface(path))
    assert leftovers(tmp_path) == []


def test_with_statistic(model: SurfaceModel) -> None:
    assert not model.valid.all() and model.valid.any()  # dropout leaves unusable pixels
    before = model.depth_mm.copy()
    for stat in STATS:
        m = model.with_statistic(stat)
        assert m.statistic == stat and m.depth_mm.dtype == np.float32
        np.testing.assert_array_equal(m.depth_mm[m.valid], getattr(model, f"{stat}_mm")[m.valid])
        assert np.all(m.depth_mm[~m.valid] == 0)
        assert m.sigma_mm is model.sigma_mm  # the other arrays are shared, not copied
    np.testing.assert_array_equal(model.depth_mm, before)  # the original is unchanged
    with pytest.raises(SurfaceError, match="use mean, mode or median"):
        model.with_statistic("max")


def _save_arrays(path: Path, model: SurfaceModel, *, meta: Any = None,
                 **over: Any) -> Path:
    """A surface file written by hand; ``meta`` is JSON-encoded (default: valid metadata);
    keyword arrays replace the model's (None leaves a key out, ``raw_meta`` replaces the
    encoded metadata array)."""
    arrays: dict[str, Any] = {
        "mean_mm": model.mean_mm, "mode_mm": model.mode_mm, "median_mm": model.median_mm,
        "sigma_mm": model.sigma_mm, "valid": model.valid, "K": model.K,
        "meta": np.asarray(json.dumps(meta if meta is not None else _meta())),
    }
    if "raw_meta" in over:
        arrays["meta"] = over.pop("raw_meta")
    arrays.update(over)
    np.savez(path, **{k: v for k, v in arrays.items() if v is not None})
    return path


def _meta(**over: Any) -> dict[str, Any]:
    return {"format": SURFACE_FORMAT, "statistic": "median", "depth_scale_m": 0.001,
            "n_frames": 12, **over}


def _flip(model: SurfaceModel, at: float) -> Callable[[Path], Path]:
    def make(d: Path) -> Path:
        p = model.save(d / "s.npz")
        data = bytearray(p.read_bytes())
        data[int(len(data) * at)] ^= 0x5A
        p.write_bytes(bytes(data))
        return p

    return make


def _bad_cases(model: SurfaceModel) -> list[tuple[str, Callable[[Path], Path], str]]:
    f32 = np.float32
    return [
        ("missing", lambda d: d / "nope.npz", "no such surface file"),
        ("folder", lambda d: d, "no such surface file"),
        ("text", lambda d: _write(d / "s.npz", b"flat table\n"), "not a depthtouch surface"),
        ("random bytes", lambda d: _write(d / "s.npz", np.random.default_rng(1).bytes(999)),
         "not a depthtouch surface"),
        ("bare npy", lambda d: _npy(d / "s.npz", model.mean_mm), "not a depthtouch surface"),
        ("a recording", lambda d: _recording(d / "s.npz"), "not a depthtouch surface"),
        ("damaged early", _flip(model, 0.1), "not a depthtouch surface"),
        ("damaged middle", _flip(model, 0.5), "not a depthtouch surface"),
        ("truncated", lambda d: _write(d / "s.npz", model.save(d / "t.npz").read_bytes()[:400]),
         "not a depthtouch surface"),
        ("no meta", lambda d: _save_arrays(d / "s.npz", model, raw_meta=None),
         "not a depthtouch surface"),
        ("meta not JSON", lambda d: _save_arrays(d / "s.npz", model, raw_meta=np.asarray("{")),
         "not a depthtouch surface"),
        ("other format", lambda d: _save_arrays(d / "s.npz", model, meta=_meta(format="x/1")),
         "not a depthtouch-surface/1 file"),
        ("meta a list", lambda d: _save_arrays(d / "s.npz", model, meta=[1, 2]),
         "not a depthtouch-surface/1 file"),
        ("statistic", lambda d: _save_arrays(d / "s.npz", model, meta=_meta(statistic="max")),
         "unknown statistic"),
        ("no n_frames", lambda d: _save_arrays(d / "s.npz", model, meta=_meta(n_frames=None)),
         "metadata incomplete"),
        ("n_frames inf", lambda d: _save_arrays(d / "s.npz", model,
                                                meta=_meta(n_frames=float("inf"))),
         "metadata incomplete"),
        ("depth_scale NaN", lambda d: _save_arrays(d / "s.npz", model,
                                                   meta=_meta(depth_scale_m=float("nan"))),
         "out of range"),
        ("depth_scale negative", lambda d: _save_arrays(d / "s.npz", model,
                                                        meta=_meta(depth_scale_m=-0.001)),
         "out of range"),
        ("shapes differ", lambda d: _save_arrays(d / "s.npz", model,
                                                 sigma_mm=model.sigma_mm[:-1]),
         "different shapes"),
        ("1-D arrays", lambda d: _save_arrays(
            d / "s.npz", model, **{k: getattr(model, k).ravel() for k in
                                   ("mean_mm", "mode_mm", "median_mm", "sigma_mm", "valid")}),
         "different shapes"),
        ("float64", lambda d: _save_arrays(d / "s.npz", model,
                                           mean_mm=model.mean_mm.astype(np.float64)),
         "unexpected array types"),
        ("valid as uint8", lambda d: _save_arrays(d / "s.npz", model,
                                                  valid=model.valid.astype(np.uint8)),
         "unexpected array types"),
        ("NaN depth", lambda d: _save_arrays(d / "s.npz", model,
                                             median_mm=np.full_like(model.median_mm, np.nan)),
         "NaN or inf"),
        ("inf sigma", lambda d: _save_arrays(d / "s.npz", model,
                                             sigma_mm=np.full_like(model.sigma_mm, f32(np.inf))),
         "NaN or inf"),
        ("K 2x2", lambda d: _save_arrays(d / "s.npz", model, K=np.eye(2)), "K is not"),
        ("K text", lambda d: _save_arrays(d / "s.npz", model, K=np.full((3, 3), "a")),
         "K is not"),
        ("K zero focal", lambda d: _save_arrays(d / "s.npz", model, K=np.zeros((3, 3))),
         "K is not"),
    ]


def _write(p: Path, data: bytes) -> Path:
    p.write_bytes(data)
    return p


def _npy(p: Path, arr: np.ndarray) -> Path:
    with p.open("wb") as fh:
        np.save(fh, arr)
    return p


def _recording(p: Path) -> Path:
    from synth import write_recording

    depth, ts = make_recording(3, [], shape=(24, 32))
    return Path(write_recording(p, depth, ts))


CASE_IDS = [c[0] for c in _bad_cases(learn_surface(np.full((2, 8, 8), 900, np.uint16), 0.001))]


@pytest.mark.parametrize("case", CASE_IDS)
def test_load_surface_errors(case: str, model: SurfaceModel, tmp_path: Path) -> None:
    _, make, needle = next(c for c in _bad_cases(model) if c[0] == case)
    path = make(tmp_path)
    with pytest.raises(SurfaceError) as e:
        load_surface(path)
    msg = str(e.value)
    assert needle in msg and "\n" not in msg, msg


def test_save_errors_leave_nothing(model: SurfaceModel, tmp_path: Path) -> None:
    with pytest.raises(SurfaceError, match="does not exist"):
        model.save(tmp_path / "nope" / "s.npz")
    (tmp_path / "dir.npz").mkdir()
    with pytest.raises(SurfaceError, match="is a folder"):
        model.save(tmp_path / "dir.npz")
    assert leftovers(tmp_path) == []
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dir.npz"]
