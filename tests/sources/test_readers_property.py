"""Property tests for every reader and parser of user files.

For each reader: malformed input (random structures, random bytes, damaged valid files) either
reads successfully with its invariants intact or raises the project's own error type
(:class:`~depthtouch.errors.DepthTouchError`) with a non-empty one-line message; never anything
else, and never a warning. Valid input round-trips exactly.
"""

from __future__ import annotations

import io
import json
import math
import os
import tempfile
import warnings
import zipfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, TypeVar

import cv2
import numpy as np
import pytest
from hypothesis import (
    HealthCheck,
    currently_in_test_context,
    event,
    example,
    given,
    settings,
)
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from depthtouch.config import PipelineConfig, config_from_dict, dump_config, load_config
from depthtouch.errors import DepthTouchError, OutputError
from depthtouch.outputs.jsonl import JsonlSink, read_events
from depthtouch.sources import NpzSource, PngFolderSource, write_npz
from depthtouch.surface.model import SURFACE_FORMAT, SurfaceModel, load_surface
from depthtouch.types import Frame, TouchEvent
from synth import result_of

T = TypeVar("T")

# modest by default (the file runs in seconds); DEPTHTOUCH_FUZZ_EXAMPLES=1000 searches harder
SETTINGS = settings(max_examples=int(os.environ.get("DEPTHTOUCH_FUZZ_EXAMPLES", "60")),
                    deadline=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
# text a UTF-8 file can hold (no lone surrogates)
UTF8 = st.characters(codec="utf-8")
K_OK = np.array([[600.0, 0, 15.5], [0, 600.0, 11.5], [0, 0, 1]])


@contextmanager
def _folder() -> Iterator[Path]:
    with tempfile.TemporaryDirectory() as d:
        yield Path(d)


def read_or_fail_cleanly(call: Callable[[], T]) -> T | None:
    """The reader's result, or None when it raised a DepthTouchError with a one-line message.

    Any other exception (or a warning, turned into an error here) fails the test.
    """
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        try:
            result = call()
        except DepthTouchError as e:
            msg = str(e)
            assert msg.strip(), f"{type(e).__name__} with an empty message"
            assert "\n" not in msg and "\r" not in msg, msg
            _event(f"refused: {type(e).__name__}")
            return None
    _event("read")
    return result


def _event(text: str) -> None:
    """Counted by --hypothesis-show-statistics: how often a reader succeeds or refuses."""
    if currently_in_test_context():
        event(text)


# --- shared strategies ---------------------------------------------------------------------------
JSON_SCALARS = (st.none() | st.booleans() | st.integers(-(2**70), 2**70)
                | st.floats(allow_nan=True, allow_infinity=True) | st.text(max_size=8))
JSON = st.recursive(JSON_SCALARS, lambda kids: st.lists(kids, max_size=4)
                    | st.dictionaries(st.text(max_size=6), kids, max_size=4), max_leaves=12)
DTYPES = ["<u2", ">u2", "u1", "i8", "f4", "f8", "?", "c8", "U3"]
ANY_ARRAY = st.sampled_from(DTYPES).flatmap(
    lambda dt: hnp.arrays(np.dtype(dt), hnp.array_shapes(min_dims=0, max_dims=4, min_side=0,
                                                         max_side=9)))
KEY = st.text(alphabet="abcdeKz_-.0", min_size=1, max_size=8)


def _deep(n: int) -> str:
    return "[" * n + "]" * n


def _mutate(data: bytes, edits: list[tuple[float, int]], cut: float | None) -> bytes:
    """Overwrite bytes at relative positions and optionally truncate."""
    b = bytearray(data)
    for pos, value in edits:
        b[min(int(pos * len(b)), len(b) - 1)] = value
    if cut is not None:
        b = b[: int(cut * len(b))]
    return bytes(b)


EDITS = st.lists(st.tuples(st.floats(0, 1), st.integers(0, 255)), min_size=1, max_size=4)
CUT = st.none() | st.floats(0, 1)


# --- .npz recordings -----------------------------------------------------------------------------
@st.composite
def _timestamps(draw: st.DrawFn, n: int) -> np.ndarray:
    steps = draw(st.lists(st.floats(1e-3, 1.0), min_size=n, max_size=n))
    return draw(st.floats(-1e3, 1e3)) + np.cumsum(steps)


@st.composite
def npz_contents(draw: st.DrawFn) -> dict[str, np.ndarray]:
    """Mostly-valid recordings with some parts replaced by random arrays or left out."""
    n = draw(st.sampled_from([1, 2, 3, 0]))
    h, w = draw(st.integers(6, 10)), draw(st.integers(6, 10))
    good = {
        "depth": hnp.arrays(np.uint16, (n, h, w)),
        "timestamps": _timestamps(n),
        "depth_scale": st.sampled_from([0.001, 0.0001, 1.0]).map(np.asarray),
        "K": st.just(K_OK),
    }
    out: dict[str, np.ndarray] = {}
    for key, strategy in good.items():
        choice = draw(st.sampled_from(["good"] * 6 + ["random", "missing"]))
        if choice == "good":
            out[key] = draw(strategy)
        elif choice == "random":
            out[key] = draw(ANY_ARRAY)
    out.update(draw(st.dictionaries(KEY, ANY_ARRAY, max_size=2)))
    return out


def _check_recording(src: NpzSource | PngFolderSource) -> None:
    frames = list(src.frames())
    assert len(frames) == len(src) >= 1
    w, h = src.resolution_wh
    t = np.array([f.timestamp_s for f in frames])
    assert np.all(np.isfinite(t)) and np.all(np.diff(t) > 0)
    assert 1e-6 <= src.depth_scale_m <= 1.0
    for i, f in enumerate(frames):
        assert f.index == i and f.depth.dtype == np.uint16 and f.depth.shape == (h, w)
    if src.K is not None:
        assert src.K.shape == (3, 3) and src.K.dtype == np.float64


@SETTINGS
@given(npz_contents())
def test_npz_reader_on_random_contents(contents: dict[str, np.ndarray]) -> None:
    with _folder() as d:
        p = d / "rec.npz"
        with p.open("wb") as fh:
            np.savez(fh, **contents)  # type: ignore[arg-type]
        src = read_or_fail_cleanly(lambda: NpzSource(p))
        if src is not None:
            read_or_fail_cleanly(lambda: _check_recording(src))
            np.testing.assert_array_equal(src.read_all(), contents["depth"])


@SETTINGS
@given(st.binary(max_size=300), EDITS, CUT)
@example(b"", [(0.0, 0)], None)
@example(b"\x93NUMPY", [(0.0, 0x93)], None)
def test_npz_reader_on_random_and_damaged_bytes(
    junk: bytes, edits: list[tuple[float, int]], cut: float | None
) -> None:
    with _folder() as d:
        (d / "junk.npz").write_bytes(b"PK\x03\x04" + junk if junk[:1] == b"P" else junk)
        assert read_or_fail_cleanly(lambda: NpzSource(d / "junk.npz")) is None
        depth = np.arange(2 * 8 * 8, dtype=np.uint16).reshape(2, 8, 8)
        good = write_npz(d / "good.npz", depth, np.array([0.0, 0.04]), 0.001, K_OK).read_bytes()
        (d / "bad.npz").write_bytes(_mutate(good, edits, cut))
        src = read_or_fail_cleanly(lambda: NpzSource(d / "bad.npz"))
        if src is not None:
            read_or_fail_cleanly(lambda: _check_recording(src))


@SETTINGS
@given(st.integers(1, 4), st.integers(8, 12), st.integers(8, 12), st.data())
def test_npz_round_trip(n: int, h: int, w: int, data: st.DataObject) -> None:
    depth = data.draw(hnp.arrays(np.uint16, (n, h, w)))
    ts = data.draw(_timestamps(n))
    scale = data.draw(st.floats(1e-6, 1.0))
    K = data.draw(st.none() | st.just(K_OK))
    with _folder() as d:
        src = NpzSource(write_npz(d / "r.npz", depth, ts, scale, K))
        np.testing.assert_array_equal(np.stack([f.depth for f in src]), depth)
        np.testing.assert_array_equal(src.timestamps, ts)
        assert src.depth_scale_m == scale
        assert (src.K is None) == (K is None)


# --- PNG folders ---------------------------------------------------------------------------------
def _png_bytes(img: np.ndarray) -> bytes:
    ok, buf = cv2.imencode(".png", img)
    assert ok
    return buf.tobytes()


FRAME_FILES = st.one_of(
    hnp.arrays(np.uint16, (9, 11)).map(_png_bytes),
    hnp.arrays(np.uint16, st.tuples(st.integers(1, 12), st.integers(1, 12))).map(_png_bytes),
    hnp.arrays(np.uint8, (9, 11)).map(_png_bytes),
    hnp.arrays(np.uint16, (9, 11, 3)).map(_png_bytes),
    st.binary(max_size=64),
    hnp.arrays(np.uint16, (9, 11)).map(_png_bytes).map(lambda b: b[: len(b) // 2]),
)
GOOD_FRAMES = st.integers(1, 3).flatmap(
    lambda n: st.lists(hnp.arrays(np.uint16, (9, 11)).map(_png_bytes), min_size=n, max_size=n))
META = st.one_of(
    st.fixed_dictionaries({"depth_scale": st.sampled_from([0.001, 0.5]),
                           "fps": st.sampled_from([30, 15.5])},
                          optional={"K": st.just(K_OK.tolist())}).map(json.dumps),
    st.fixed_dictionaries(
        {"depth_scale": st.sampled_from([0.001, 0.5]) | JSON_SCALARS},
        optional={"fps": st.sampled_from([30, 15.5]) | JSON_SCALARS,
                  "K": st.just(K_OK.tolist()) | JSON},
    ).map(json.dumps),
    JSON.map(json.dumps),
    st.text(UTF8, max_size=20),
)
TIMESTAMPS_TXT = st.none() | st.text(alphabet="0123456789.e-+ \nnaif", max_size=30) | st.lists(
    st.floats(allow_nan=True), max_size=4).map(lambda v: "".join(f"{x!r}\n" for x in v))


@SETTINGS
@given(META, GOOD_FRAMES | st.lists(FRAME_FILES, min_size=0, max_size=3),
       st.none() | st.none() | TIMESTAMPS_TXT)
@example(_deep(100_000), [], None)
def test_png_folder_reader_on_random_contents(
    meta: str, frames: list[bytes], timestamps: str | None
) -> None:
    with _folder() as d:
        root = d / "rec"
        (root / "depth").mkdir(parents=True)
        (root / "meta.json").write_text(meta, encoding="utf-8")
        for i, data in enumerate(frames):
            (root / "depth" / f"{i:06d}.png").write_bytes(data)
        if timestamps is not None:
            (root / "timestamps.txt").write_text(timestamps, encoding="utf-8")
        src = read_or_fail_cleanly(lambda: PngFolderSource(root))
        if src is not None:
            read_or_fail_cleanly(lambda: _check_recording(src))


@SETTINGS
@given(st.integers(1, 3), st.integers(8, 12), st.integers(8, 12), st.data())
def test_png_folder_round_trip(n: int, h: int, w: int, data: st.DataObject) -> None:
    from depthtouch.sources import write_png_folder

    depth = data.draw(hnp.arrays(np.uint16, (n, h, w)))
    ts = data.draw(_timestamps(n))
    scale = data.draw(st.floats(1e-6, 1.0))
    with _folder() as d:
        src = PngFolderSource(write_png_folder(d / "r", depth, ts, scale, K_OK))
        np.testing.assert_array_equal(np.stack([f.depth for f in src]), depth)
        np.testing.assert_array_equal(src.timestamps, ts)
        assert src.depth_scale_m == scale
        np.testing.assert_array_equal(src.K, K_OK)


# --- surface files -------------------------------------------------------------------------------
SURFACE_ARRAYS = ("mean_mm", "mode_mm", "median_mm", "sigma_mm")


@st.composite
def surface_models(draw: st.DrawFn) -> SurfaceModel:
    h, w = draw(st.integers(1, 6)), draw(st.integers(1, 6))
    finite = st.floats(-1e6, 1e6, width=32)
    arrs = [draw(hnp.arrays(np.float32, (h, w), elements=finite)) for _ in range(4)]
    valid = draw(hnp.arrays(np.bool_, (h, w)))
    K = draw(st.none() | st.just(K_OK))
    base = SurfaceModel(arrs[2], arrs[0], arrs[1], arrs[2], np.abs(arrs[3]), valid, "median",
                        draw(st.floats(1e-6, 1.0)), K, draw(st.integers(1, 10**6)))
    return base.with_statistic(draw(st.sampled_from(["mean", "mode", "median"])))


@st.composite
def surface_contents(draw: st.DrawFn) -> dict[str, np.ndarray]:
    """Mostly-valid surface files with parts replaced, left out or added."""
    m = draw(surface_models())
    meta: Any = {"format": SURFACE_FORMAT, "statistic": m.statistic,
                 "depth_scale_m": m.depth_scale_m, "n_frames": m.n_frames}
    for key in list(meta):
        choice = draw(st.sampled_from(["keep", "keep", "keep", "random", "drop"]))
        if choice == "random":
            meta[key] = draw(JSON)
        elif choice == "drop":
            del meta[key]
    if draw(st.booleans()):
        meta = draw(JSON) if draw(st.booleans()) else meta
    out: dict[str, np.ndarray] = {k: getattr(m, k) for k in SURFACE_ARRAYS}
    out["valid"] = m.valid
    out["meta"] = np.asarray(json.dumps(meta))
    if m.K is not None:
        out["K"] = m.K
    for key in list(out):
        choice = draw(st.sampled_from(["keep", "keep", "keep", "random", "drop"]))
        if choice == "random":
            out[key] = draw(ANY_ARRAY)
        elif choice == "drop":
            del out[key]
    out.update(draw(st.dictionaries(KEY, ANY_ARRAY, max_size=1)))
    return out


def _check_surface(s: SurfaceModel) -> None:
    shape = s.depth_mm.shape
    assert len(shape) == 2 and s.valid.dtype == np.bool_
    for k in ("depth_mm", *SURFACE_ARRAYS):
        a = getattr(s, k)
        assert a.shape == shape and a.dtype == np.float32 and np.all(np.isfinite(a))
    assert s.statistic in ("mean", "mode", "median")
    assert 1e-6 <= s.depth_scale_m <= 1.0 and s.n_frames >= 1
    s.mm_per_px()  # usable with its K


@SETTINGS
@given(surface_contents())
def test_surface_reader_on_random_contents(contents: dict[str, np.ndarray]) -> None:
    with _folder() as d:
        p = d / "s.npz"
        with p.open("wb") as fh:
            np.savez(fh, **contents)  # type: ignore[arg-type]
        s = read_or_fail_cleanly(lambda: load_surface(p))
        if s is not None:
            _check_surface(s)


@SETTINGS
@given(surface_models(), st.binary(max_size=200), EDITS, CUT)
def test_surface_reader_on_random_and_damaged_bytes(
    model: SurfaceModel, junk: bytes, edits: list[tuple[float, int]], cut: float | None
) -> None:
    with _folder() as d:
        (d / "junk.npz").write_bytes(junk)
        assert read_or_fail_cleanly(lambda: load_surface(d / "junk.npz")) is None
        good = model.save(d / "good.npz").read_bytes()
        (d / "bad.npz").write_bytes(_mutate(good, edits, cut))
        s = read_or_fail_cleanly(lambda: load_surface(d / "bad.npz"))
        if s is not None:
            _check_surface(s)


@SETTINGS
@given(surface_models())
def test_surface_round_trip(model: SurfaceModel) -> None:
    with _folder() as d:
        back = load_surface(model.save(d / "s.npz"))
    for k in ("depth_mm", "valid", *SURFACE_ARRAYS):
        np.testing.assert_array_equal(getattr(back, k), getattr(model, k), err_msg=k)
    assert (back.statistic, back.depth_scale_m, back.n_frames) == (
        model.statistic, model.depth_scale_m, model.n_frames)
    assert (back.K is None) == (model.K is None)


# --- config files --------------------------------------------------------------------------------
_TOML_ESC = {'"': '\\"', "\\": "\\\\", "\n": "\\n", "\t": "\\t", "\r": "\\r", "\b": "\\b",
             "\f": "\\f"}


def _toml_str(s: str) -> str:
    return '"' + "".join(_TOML_ESC.get(c, c if ord(c) >= 0x20 and ord(c) != 0x7F
                                        else f"\\u{ord(c):04x}") for c in s) + '"'


def _toml(v: Any) -> str:
    """A value as TOML text (inline tables and arrays), for generating config files."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return "nan" if math.isnan(v) else repr(v)
    if isinstance(v, str):
        return _toml_str(v)
    if isinstance(v, list):
        return "[" + ", ".join(_toml(x) for x in v) + "]"
    return "{" + ", ".join(f"{_toml_str(k)} = {_toml(x)}" for k, x in v.items()) + "}"


SECTIONS = {name: [f for f in getattr(PipelineConfig(), name).__dataclass_fields__]
            for name in PipelineConfig.__dataclass_fields__}
TOML_SCALARS = (st.booleans() | st.integers(-(2**63), 2**63 - 1) | st.integers()
                | st.floats(allow_nan=False) | st.just(float("nan")) | st.text(UTF8, max_size=6))
TOML_VALUES = st.recursive(TOML_SCALARS, lambda kids: st.lists(kids, max_size=3)
                           | st.dictionaries(st.text(UTF8, max_size=5), kids, max_size=3), max_leaves=8)


@st.composite
def config_tables(draw: st.DrawFn) -> dict[str, Any]:
    """Tables of known and unknown sections and keys with valid-looking and random values."""
    doc: dict[str, Any] = {}
    names = draw(st.lists(st.sampled_from(sorted(SECTIONS)) | st.text(UTF8, max_size=6), max_size=3))
    for section in names:
        if section not in SECTIONS:
            doc[section] = draw(TOML_VALUES)
            continue
        table: dict[str, Any] = {}
        for key in draw(st.lists(st.sampled_from(SECTIONS[section]) | st.text(UTF8, max_size=5),
                                 max_size=3)):
            default = getattr(getattr(PipelineConfig(), section), key, None)
            near = (st.floats(0.0, 2.0 * default) if isinstance(default, float)
                    else st.nothing())
            table[key] = draw(near | TOML_VALUES)
        doc[section] = table
    return doc


@SETTINGS
@given(config_tables())
def test_config_reader_on_random_tables(doc: dict[str, Any]) -> None:
    text = "\n".join(f"{_toml_str(k)} = {_toml(v)}" for k, v in doc.items())
    import tomllib

    parsed = tomllib.loads(text)  # the generator writes valid TOML
    assert parsed.keys() == doc.keys()
    with _folder() as d:
        (d / "c.toml").write_text(text, encoding="utf-8")
        cfg = read_or_fail_cleanly(lambda: load_config(d / "c.toml"))
    if cfg is not None:
        for section, table in parsed.items():
            for key, value in table.items():
                got = getattr(getattr(cfg, section), key)
                assert got == value or (key == "params" and dict(got) == value), (section, key)


@SETTINGS
@given(st.text(max_size=80) | st.binary(max_size=80))
@example("[surface]\nlearn_s = " + "9" * 500)
@example("a = " + _deep(5000))
def test_config_reader_on_random_text(text: str | bytes) -> None:
    with _folder() as d:
        p = d / "c.toml"
        if isinstance(text, bytes):
            p.write_bytes(text)
        else:
            p.write_text(text, encoding="utf-8", errors="surrogatepass")
        read_or_fail_cleanly(lambda: load_config(p))


@st.composite
def valid_configs(draw: st.DrawFn) -> PipelineConfig:
    """Random configs that validate: numbers near the defaults, random filter settings."""
    doc: dict[str, Any] = {}
    for section, fields in SECTIONS.items():
        table: dict[str, Any] = {}
        for key in fields:
            default = getattr(getattr(PipelineConfig(), section), key)
            if isinstance(default, bool):
                table[key] = draw(st.booleans())
            elif isinstance(default, float) and draw(st.booleans()):
                table[key] = draw(st.floats(0.5, 1.5)) * default
            elif isinstance(default, int) and draw(st.booleans()):
                # odd defaults move by two and stay odd (kernel sizes need a centre pixel)
                step = 2 if default % 2 else 1
                table[key] = max(default + step * draw(st.integers(-1, 1)), 1)
        doc[section] = table
    doc["filter"] = {"name": draw(st.text(max_size=8)),
                     "params": draw(st.dictionaries(st.text(max_size=6),
                                                    st.floats(allow_nan=False,
                                                              allow_infinity=False)
                                                    | st.integers(-(2**63), 2**63 - 1),
                                                    max_size=3))}
    try:
        return config_from_dict(doc)
    except DepthTouchError:
        from hypothesis import reject

        reject()


@SETTINGS
@given(valid_configs())
def test_config_round_trip(cfg: PipelineConfig) -> None:
    with _folder() as d:
        (d / "c.toml").write_text(dump_config(cfg), encoding="utf-8")
        assert load_config(d / "c.toml") == cfg


# --- events files --------------------------------------------------------------------------------
FINITE = st.floats(allow_nan=False, allow_infinity=False, min_value=-1e12, max_value=1e12)
EVENTS = st.builds(
    TouchEvent, frame=st.integers(0, 10**9), t=FINITE, id=st.integers(0, 10**9),
    state=st.sampled_from(["down", "move", "up"]), x=FINITE, y=FINITE,
    extra=st.dictionaries(st.sampled_from(["sx", "sy", "area", "h", "X", "e_note"]),
                          FINITE | st.integers(0, 10**6) | st.text(max_size=4), max_size=3),
)
LINES = st.lists(
    EVENTS.map(lambda e: json.dumps(e.to_dict()))
    | EVENTS.map(lambda e: json.dumps({**e.to_dict(), "frame": -1}))
    | st.dictionaries(st.sampled_from(["frame", "t", "id", "state", "x", "y"]), JSON_SCALARS)
    .map(json.dumps)
    | JSON.map(json.dumps)
    | st.text(alphabet=st.characters(blacklist_characters="\n\r\x0b\x0c\x1c\x1d\x1e\x85\u2028"
                                     "\u2029", codec="utf-8"), max_size=20),  # a file's text
    max_size=5,
)


@SETTINGS
@given(LINES)
@example([_deep(100_000)])
@example(['{"frame": Infinity, "t": 0, "id": 1, "state": "down", "x": 1, "y": 2}'])
def test_events_reader_on_random_lines(lines: list[str]) -> None:
    with _folder() as d:
        p = d / "ev.jsonl"
        p.write_text("".join(line + "\n" for line in lines), encoding="utf-8")
        got = read_or_fail_cleanly(lambda: list(read_events(p)))
    if got is not None:
        assert len(got) == sum(1 for line in lines if line.strip())
        for e in got:
            assert e.state in ("down", "move", "up") and e.frame >= 0 and e.id >= 0
            assert all(math.isfinite(v) for v in (e.t, e.x, e.y))


@SETTINGS
@given(st.binary(max_size=100))
def test_events_reader_on_random_bytes(data: bytes) -> None:
    with _folder() as d:
        (d / "ev.jsonl").write_bytes(data)
        read_or_fail_cleanly(lambda: list(read_events(d / "ev.jsonl")))


@SETTINGS
@given(st.lists(EVENTS, max_size=6))
def test_events_round_trip(events: list[TouchEvent]) -> None:
    frame = Frame(np.zeros((2, 2), np.uint16), 0.0, 0)
    with _folder() as d:
        with JsonlSink(d / "ev.jsonl") as sink:
            sink.send(result_of(frame, events))
        back = list(read_events(d / "ev.jsonl"))
    assert [e.to_dict() for e in back] == [e.to_dict() for e in events]


def test_events_reader_names_the_line() -> None:
    with _folder() as d:
        good = json.dumps(TouchEvent(1, 0.5, 2, "down", 3.0, 4.0).to_dict())
        (d / "ev.jsonl").write_text(f"{good}\n\n{good}\n{{\"frame\": 1}}\n")
        with pytest.raises(OutputError, match=r"ev\.jsonl:4: not a touch event \(no 't' field\)"):
            list(read_events(d / "ev.jsonl"))


# --- calibration files ---------------------------------------------------------------------------
def _calibration_module() -> Any:
    return pytest.importorskip("depthtouch.calibration")


H_ENTRIES = st.floats(-0.2, 0.2)


@st.composite
def calibrations(draw: st.DrawFn) -> Any:
    cal = _calibration_module()
    H = np.diag([draw(st.floats(0.5, 4.0)), draw(st.floats(0.5, 4.0)), 1.0])
    H[0, 1], H[1, 0] = draw(H_ENTRIES), draw(H_ENTRIES)
    H[0, 2], H[1, 2] = draw(st.floats(-500, 500)), draw(st.floats(-500, 500))
    H[2, 0], H[2, 1] = draw(st.floats(-1e-4, 1e-4)), draw(st.floats(-1e-4, 1e-4))
    return cal.Calibration(H, (draw(st.integers(1, 8000)), draw(st.integers(1, 8000))),
                           draw(st.floats(0, 50)))


@SETTINGS
@given(calibrations(), st.data())
def test_calibration_reader_on_random_and_damaged_files(base: Any, data: Any) -> None:
    cal = _calibration_module()
    with _folder() as d:
        p = d / "cal.json"
        doc = cal.calibration_to_dict(base)
        choice = data.draw(st.sampled_from(["value", "drop", "whole", "text"]))
        if choice == "value":
            doc[data.draw(st.sampled_from(sorted(doc)))] = data.draw(JSON)
        elif choice == "drop":
            del doc[data.draw(st.sampled_from(sorted(doc)))]
        elif choice == "whole":
            doc = data.draw(JSON)
        p.write_text(json.dumps(doc) if choice != "text" else data.draw(st.text(UTF8, max_size=30)))
        got = read_or_fail_cleanly(lambda: cal.load_calibration(p))
    if got is not None:
        assert got.H.shape == (3, 3) and np.all(np.isfinite(got.H))


@pytest.mark.parametrize("text", [
    "{", "\udcff", "[]", "null",
    _deep(100_000),
], ids=["truncated", "not utf-8", "list", "null", "deep nesting"])
def test_calibration_reader_on_broken_json(text: str) -> None:
    cal = _calibration_module()
    with _folder() as d:
        p = d / "cal.json"
        p.write_bytes(text.encode("utf-8", errors="surrogateescape"))
        assert read_or_fail_cleanly(lambda: cal.load_calibration(p)) is None


@SETTINGS
@given(calibrations())
def test_calibration_round_trip(c: Any) -> None:
    cal = _calibration_module()
    with _folder() as d:
        back = cal.load_calibration(cal.save_calibration(c, d / "cal.json"))
    np.testing.assert_array_equal(back.H, c.H)
    assert back.screen_wh == c.screen_wh
    assert back.reprojection_error_px == c.reprojection_error_px


# --- simulator truth files -----------------------------------------------------------------------
def _truth_doc(n_frames: int, contacts: list[dict[str, float]]) -> dict[str, Any]:
    return {
        "format": "depthtouch-truth/1", "scene": "taps", "seed": 1,
        "camera": {"profile": "d435", "resolution_wh": [32, 24], "K": K_OK.tolist(),
                   "depth_scale": 0.001, "fps": 30.0},
        "surface": {"kind": "plane"}, "empty_frames": 1,
        "frames": [{"frame": i, "t": i / 30.0, "contacts": contacts if i else [], "hovers": []}
                   for i in range(n_frames)],
        "events": [{"kind": "tap", "frame": 1}],
    }


CONTACT = st.fixed_dictionaries({k: st.floats(-100, 100) for k in
                                 ("id", "x", "y", "X", "Y", "Z", "nx", "ny", "nz")})


def _mutated_truth(draw: st.DrawFn) -> Any:
    doc: Any = _truth_doc(draw(st.integers(1, 3)), draw(st.lists(CONTACT, max_size=2)))
    for _ in range(draw(st.integers(0, 2))):
        target = doc
        path = draw(st.lists(st.sampled_from(["camera", "frames", 0, "K", "contacts", "fps"]),
                             max_size=2))
        for step in path:
            if isinstance(target, dict) and step in target:
                target = target[step]
            elif isinstance(target, list) and isinstance(step, int) and target:
                target = target[0]
        if isinstance(target, dict) and target:
            target[draw(st.sampled_from(sorted(target)))] = draw(JSON)
    return doc


MUTATED_TRUTHS = st.composite(_mutated_truth)()


#: found by the search: a truth whose scene is [NaN] reads back equal, NaN and all
_NAN_SCENE = {"format": "depthtouch-truth/1", "scene": [math.nan], "seed": 1,
              "camera": {"profile": "d435", "resolution_wh": [32, 24],
                         "K": [[600.0, 0.0, 15.5], [0.0, 600.0, 11.5], [0.0, 0.0, 1.0]],
                         "depth_scale": 0.001, "fps": 30.0},
              "surface": {"kind": "plane"}, "empty_frames": 1,
              "frames": [{"frame": 0, "t": 0.0, "contacts": [], "hovers": []}],
              "events": [{"kind": "tap", "frame": 1}]}


@SETTINGS
@given(MUTATED_TRUTHS | JSON)
@example(_NAN_SCENE)
def test_truth_readers_on_random_and_damaged_files(doc: Any) -> None:
    sim = pytest.importorskip("depthtouch.sim")
    from depthtouch.evaluation.metrics import read_truth

    with _folder() as d:
        p = d / "t.json"
        p.write_text(json.dumps(doc))
        got = read_or_fail_cleanly(lambda: sim.load_truth(p))
        if got is not None:
            # as JSON text: a NaN that the file holds (Python's json writes and reads it) is
            # read back as NaN, which compares unequal to itself
            assert json.dumps(got, sort_keys=True) == json.dumps(doc, sort_keys=True)
        read_or_fail_cleanly(lambda: read_truth(p))


@pytest.mark.parametrize("reader", ["sim.load_truth", "evaluation.read_truth"])
@pytest.mark.parametrize("text", ["{", "\udcff", "[]", _deep(100_000)],
                         ids=["truncated", "not utf-8", "list", "deep nesting"])
def test_truth_readers_on_broken_json(reader: str, text: str) -> None:
    sim = pytest.importorskip("depthtouch.sim")
    from depthtouch.evaluation.metrics import read_truth

    read = sim.load_truth if reader == "sim.load_truth" else read_truth
    with _folder() as d:
        p = d / "t.json"
        p.write_bytes(text.encode("utf-8", errors="surrogateescape"))
        assert read_or_fail_cleanly(lambda: read(p)) is None


@SETTINGS
@given(st.integers(1, 4), st.lists(CONTACT, max_size=3))
def test_truth_round_trip(n: int, contacts: list[dict[str, float]]) -> None:
    sim = pytest.importorskip("depthtouch.sim")
    doc = _truth_doc(n, contacts)
    with _folder() as d:
        (d / "t.json").write_text(json.dumps(doc))
        assert sim.load_truth(d / "t.json") == doc


def test_zip_members_that_are_not_arrays() -> None:
    """An archive member without the .npy format reads as bytes in numpy; both readers say so."""
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as z:
        for name in ("depth", "meta", "mean_mm"):
            z.writestr(name, b"raw bytes")
    with _folder() as d:
        (d / "x.npz").write_bytes(buf.getvalue())
        assert read_or_fail_cleanly(lambda: NpzSource(d / "x.npz")) is None
        assert read_or_fail_cleanly(lambda: load_surface(d / "x.npz")) is None
