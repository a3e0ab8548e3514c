"""RealSense sources without a camera: mode choice, error paths, and recordings written with the
SDK's own software device + recorder, played back through pyrealsense2, compared with .npz."""

from __future__ import annotations

import builtins
import sys
from pathlib import Path

import numpy as np
import pytest

from depthtouch.errors import SourceError
from depthtouch.pipeline import Pipeline
from depthtouch.sources import NpzSource, open_source, write_npz
from depthtouch.sources.realsense import RealSenseSource, choose_depth_mode
from depthtouch.sources.realsense_record import RealSenseRecordingWriter, write_realsense_recording
from depthtouch.types import Frame
from synth import Finger, make_recording

try:
    import pyrealsense2 as rs
except ImportError:  # the SDK-free tests below still run
    rs = None
needs_rs = pytest.mark.skipif(rs is None, reason="pyrealsense2 is not installed")

K_CROP = np.array([[600.0, 0, 159.5], [0, 600.0, 119.5], [0, 0, 1]])
D435_MODES = [(848, 480, f) for f in (6, 15, 30, 60, 90)] + [
    (640, 480, f) for f in (6, 15, 30, 60, 90)] + [(1280, 720, f) for f in (6, 15, 30)]
D415_MODES = [(848, 480, f) for f in (6, 15, 30, 60)] + [(1280, 720, f) for f in (6, 15, 30)]
L_MODES = [(1024, 768, 30), (640, 480, 30)]


@pytest.mark.parametrize(
    ("modes", "wh", "fps", "want"),
    [
        (D435_MODES, None, None, (848, 480, 90)),
        (D415_MODES, None, None, (848, 480, 30)),  # no 90 fps at 848x480: fall back to 30
        (D435_MODES, (1280, 720), None, (1280, 720, 30)),
        (D435_MODES, (640, 480), 60, (640, 480, 60)),
        (L_MODES, None, None, (640, 480, 30)),
        ([(1024, 768, 30)], None, None, (1024, 768, 30)),  # nothing preferred: the only mode
        ([(848, 480, 15)], None, None, (848, 480, 15)),  # neither 90 nor 30: the fastest
        (D415_MODES, (640, 480), None, "no 640x480 depth mode; choose one of 1280x720, 848x480"),
        (D415_MODES, None, 90, "no 90 fps at 848x480; choose one of 60, 30, 15, 6"),
        ([], None, None, "no Z16 depth mode"),
    ],
)
def test_choose_depth_mode(modes, wh, fps, want):  # type: ignore[no-untyped-def]
    if isinstance(want, str):
        with pytest.raises(SourceError, match=want):
            choose_depth_mode(modes, wh, fps)
    else:
        assert choose_depth_mode(modes, wh, fps) == want


def _one_line(e: pytest.ExceptionInfo[BaseException]) -> str:
    text = str(e.value)
    assert "\n" not in text
    return text


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"preset": "fastest"}, "unknown RealSense preset 'fastest'; use one of high_accuracy"),
        ({"resolution_wh": "848*480"}, "not WIDTHxHEIGHT"),
        ({"post_processing": ["decimation"]}, "unknown post-processing filter 'decimation'"),
        ({"frame_timeout_s": 0}, "must be > 0"),
    ],
)
def test_live_source_rejects_bad_options(kwargs, match):  # type: ignore[no-untyped-def]
    with pytest.raises(SourceError, match=match) as e:
        RealSenseSource(**kwargs)
    _one_line(e)


@needs_rs
def test_no_camera_gives_one_line_error():
    if len(rs.context().query_devices()):
        pytest.skip("a RealSense camera is connected")
    with pytest.raises(SourceError, match="no RealSense camera found; connect one") as e:
        open_source("realsense")
    _one_line(e)
    with pytest.raises(SourceError, match="no RealSense camera found"):
        open_source("realsense:012345678901", fps=30)


@pytest.mark.parametrize("spec", ["realsense", "session.db3", "session.bag"])
def test_missing_package_gives_install_hint(monkeypatch, tmp_path, spec):  # type: ignore[no-untyped-def]
    monkeypatch.setitem(sys.modules, "pyrealsense2", None)
    path = tmp_path / spec
    if spec != "realsense":
        path.write_bytes(b"x")
    with pytest.raises(SourceError, match=r"pip install 'depthtouch\[realsense\]'") as e:
        open_source(path if spec != "realsense" else spec)
    _one_line(e)


def test_missing_libusb_gives_apt_hint(monkeypatch):  # type: ignore[no-untyped-def]
    real_import = builtins.__import__

    def fake_import(name, *args, **kwargs):  # type: ignore[no-untyped-def]
        if name == "pyrealsense2":
            raise ImportError("libusb-1.0.so.0: cannot open shared object file")
        return real_import(name, *args, **kwargs)

    monkeypatch.delitem(sys.modules, "pyrealsense2", raising=False)
    monkeypatch.setattr(builtins, "__import__", fake_import)
    with pytest.raises(SourceError, match="apt-get install libusb-1.0-0") as e:
        open_source("realsense")
    _one_line(e)


# --- recordings -------------------------------------------------------------------------------
def _scene(seed: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """50 empty frames (the surface), a drag to the right, a lift, a drag downward."""
    script = ([[Finger(100 + 3 * i, 120)] for i in range(20)] + [[]] * 5
              + [[Finger(200, 80 + 2 * i, direction_deg=0)] for i in range(15)] + [[]] * 3)
    return make_recording(50, script, shape=(240, 320), seed=seed)


def _events(source):  # type: ignore[no-untyped-def]
    p = Pipeline()
    out = []
    with source:
        for f in source.frames():
            out += [e.to_dict() for e in p.process(f).events]
    end = p.finish()
    return out + [e.to_dict() for e in (end.events if end is not None else [])]


@needs_rs
@pytest.mark.parametrize("scale", [0.001, 0.00025])
def test_db3_round_trip_matches_npz(tmp_path, scale):  # type: ignore[no-untyped-def]
    depth_mm, ts = _scene()
    depth = np.rint(depth_mm.astype(np.float64) * (0.001 / scale)).astype(np.uint16)
    npz = write_npz(tmp_path / "scene.npz", depth, ts, scale, K_CROP)
    db3 = write_realsense_recording(tmp_path / "scene.db3", depth, ts, scale, K_CROP)
    assert db3.is_file() and not list(tmp_path.glob(".scene.*"))  # no temporary left behind

    src = open_source(db3)
    assert src.depth_scale_m == scale
    np.testing.assert_allclose(src.K, K_CROP, rtol=1e-6)
    assert src.resolution_wh == (320, 240) and src.fps == 30.0
    frames = list(src.frames())
    assert len(frames) == len(depth)
    for i, f in enumerate(frames):
        assert f.index == i and np.array_equal(f.depth, depth[i])
    np.testing.assert_allclose([f.timestamp_s for f in frames], ts, atol=1e-6)
    assert len(list(src.frames())) == len(depth)  # a second pass starts again
    src.close()

    if scale != 0.001:
        return  # the events are compared once; the units and frames above for each scale
    ev_npz = _events(NpzSource(npz))
    ev_db3 = _events(open_source(db3))
    states = [e["state"] for e in ev_npz]
    assert states.count("down") == 2 and states.count("up") == 2
    assert ev_db3 == ev_npz


@needs_rs
def test_bag_round_trip_where_the_sdk_writes_bag(tmp_path):  # type: ignore[no-untyped-def]
    depth, ts = make_recording(5, [[Finger(100, 100)]] * 3, shape=(48, 64), seed=1)
    try:
        path = write_realsense_recording(tmp_path / "s.bag", depth, ts, 0.001, None)
    except SourceError as e:
        assert "writes only .db3 recordings; use a .db3 name" in str(e)
        assert not list(tmp_path.iterdir())
        pytest.skip(f"pyrealsense2 {rs.__version__} writes only .db3")
    frames = list(open_source(path).frames())
    assert [f.depth.tolist() for f in frames] == depth.tolist()


@needs_rs
def test_writer_streams_frames_and_keeps_missing_K(tmp_path):  # type: ignore[no-untyped-def]
    rng = np.random.default_rng(7)
    depth = rng.integers(0, 65535, (12, 30, 40), dtype=np.uint16)
    with RealSenseRecordingWriter(tmp_path / "w.db3", (40, 30), 0.0001, None, fps=90) as w:
        for i in range(len(depth)):
            w.write(depth[i], 100.0 + i / 90)
    src = open_source(tmp_path / "w.db3")
    assert src.fps == 90.0 and src.depth_scale_m == 0.0001
    got = list(src.frames())
    assert np.array_equal(np.stack([f.depth for f in got]), depth)
    assert abs(got[0].timestamp_s - 100.0) < 1e-6


@needs_rs
def test_interrupted_writer_keeps_no_file(tmp_path):  # type: ignore[no-untyped-def]
    with pytest.raises(RuntimeError), \
            RealSenseRecordingWriter(tmp_path / "x.db3", (16, 16)) as w:
        w.write(np.zeros((16, 16), np.uint16), 0.0)
        raise RuntimeError("boom")
    assert not list(tmp_path.iterdir())


@needs_rs
@pytest.mark.parametrize(
    ("name", "content", "match"),
    [
        ("missing.db3", None, "no such file"),
        ("junk.db3", b"not a database", "not a readable RealSense recording"),
        ("junk.bag", b"#ROSBAG V2.0\n", "not a readable RealSense recording"),
    ],
)
def test_playback_errors(tmp_path, name, content, match):  # type: ignore[no-untyped-def]
    path = tmp_path / name
    if content is not None:
        path.write_bytes(content)
    with pytest.raises(SourceError, match=match) as e:
        open_source(path)
    _one_line(e)


@needs_rs
@pytest.mark.parametrize(
    ("target", "wh", "frame", "match"),
    [
        ("x.npz", (16, 16), None, "must end in .db3"),
        ("nofolder/x.db3", (16, 16), None, "does not exist"),
        ("x.db3", (16, 16), np.zeros((8, 16), np.uint16), "does not match"),
        ("x.db3", (16, 16), np.zeros((16, 16), np.float32), "does not match"),
    ],
)
def test_writer_errors(tmp_path, target, wh, frame, match):  # type: ignore[no-untyped-def]
    with pytest.raises(SourceError, match=match), \
            RealSenseRecordingWriter(tmp_path / target, wh) as w:
        w.write(frame, 0.0)
    assert not [p for p in tmp_path.iterdir() if p.suffix == ".db3"]


@needs_rs
def test_frames_are_copies(tmp_path):  # type: ignore[no-untyped-def]
    depth = np.arange(5 * 16 * 16, dtype=np.uint16).reshape(5, 16, 16)
    p = write_realsense_recording(tmp_path / "c.db3", depth, np.arange(5) / 30.0)
    frames: list[Frame] = list(open_source(p).frames())  # the SDK recycles its buffers
    assert all(np.array_equal(f.depth, depth[i]) for i, f in enumerate(frames))
    assert all(f.depth.flags.writeable and f.depth.base is None for f in frames)


@needs_rs
@pytest.mark.parametrize(
    ("fps", "crop"),
    [
        (10.0, (slice(120, 360), slice(212, 636))),  # reduced: fewer frames, the centre only
        pytest.param(30.0, None, marks=pytest.mark.slow),
    ],
)
def test_sim_scene_round_trip(tmp_path: Path, fps, crop):  # type: ignore[no-untyped-def]
    """The simulator's taps scene gives the same events from .db3 as from .npz."""
    sim = pytest.importorskip("depthtouch.sim")
    rec = sim.render_scene("taps", camera="realsense-d435", seed=0, fps=fps)
    depth, K = rec.depth, rec.K.copy()
    if crop is not None:
        depth = np.ascontiguousarray(depth[:, crop[0], crop[1]])
        K[0, 2] -= crop[1].start
        K[1, 2] -= crop[0].start
    ts = rec.timestamps_s
    npz = write_npz(tmp_path / "taps.npz", depth, ts, rec.depth_scale_m, K)
    db3 = write_realsense_recording(tmp_path / "taps.db3", depth, ts, rec.depth_scale_m, K)
    src = open_source(db3)
    assert src.depth_scale_m == rec.depth_scale_m
    np.testing.assert_allclose(src.K, K, rtol=1e-6)
    ev_npz, ev_db3 = _events(NpzSource(npz)), _events(src)
    assert [e["state"] for e in ev_npz].count("down") >= 3
    assert ev_db3 == ev_npz


# --- OpenNI 2 (second live source): error paths and the glue, against a stand-in module -------
class _Mode:
    def __init__(self, fmt: int, w: int, h: int, fps: int) -> None:
        self.pixelFormat, self.resolutionX, self.resolutionY, self.fps = fmt, w, h, fps


class _NiFrame:
    def __init__(self, depth: np.ndarray, t_us: int) -> None:
        self._d, self.timestamp = depth, t_us
        self.height, self.width = depth.shape

    def get_buffer_as_uint16(self) -> np.ndarray:
        return self._d.reshape(-1)


class _NiStream:
    def __init__(self, frames: list[np.ndarray]) -> None:
        self.frames, self.mode, self.started, self.stopped = frames, None, False, False
        self.i = 0

    def get_sensor_info(self):  # type: ignore[no-untyped-def]
        info = type("Info", (), {})()
        info.videoModes = [_Mode(100, 640, 480, 30), _Mode(101, 320, 240, 60),
                           _Mode(100, 320, 240, 60), _Mode(200, 640, 480, 90)]
        return info

    def set_video_mode(self, m):  # type: ignore[no-untyped-def]
        self.mode = m

    def start(self) -> None:
        self.started = True

    def stop(self) -> None:
        self.stopped = True

    def close(self) -> None:
        pass

    def get_horizontal_fov(self) -> float:
        return 1.0225  # 58.6 deg, Xtion

    def get_vertical_fov(self) -> float:
        return 0.7976

    def read_frame(self) -> _NiFrame:
        f = _NiFrame(self.frames[self.i], 1_000_000 + 33_333 * self.i)
        self.i += 1
        return f


def _fake_openni(monkeypatch, *, init_error=False, device=True, frames=()):  # type: ignore[no-untyped-def]
    import types

    stream = _NiStream(list(frames))
    ni = types.ModuleType("openni.openni2")

    def initialize(dirs):  # type: ignore[no-untyped-def]
        if init_error:
            raise OSError("libOpenNI2.so: cannot open shared object file")

    class Device:
        @staticmethod
        def open_any():  # type: ignore[no-untyped-def]
            if not device:
                raise RuntimeError("DeviceOpen using default: no devices found")
            return types.SimpleNamespace(create_depth_stream=lambda: stream, close=lambda: None)

        open_file = open_any

    ni.initialize = initialize  # type: ignore[attr-defined]
    ni.Device = Device  # type: ignore[attr-defined]
    ni.wait_for_any_stream = (  # type: ignore[attr-defined]
        lambda streams, timeout: streams[0] if stream.i < len(stream.frames) else None)
    pkg = types.ModuleType("openni")
    pkg.openni2 = ni  # type: ignore[attr-defined]
    monkeypatch.setitem(sys.modules, "openni", pkg)
    monkeypatch.setitem(sys.modules, "openni.openni2", ni)
    return stream


@pytest.mark.parametrize(
    ("setup", "match"),
    [
        ({"missing": True}, r"openni package is not installed; pip install 'depthtouch\[openni\]'"),
        ({"init_error": True}, "OpenNI 2 runtime cannot be loaded; install the OpenNI 2 runtime"),
        ({"device": False}, "no OpenNI device connected .*; plug the camera in"),
    ],
)
def test_openni_errors(monkeypatch, setup, match):  # type: ignore[no-untyped-def]
    if setup.pop("missing", False):
        monkeypatch.setitem(sys.modules, "openni", None)
    else:
        _fake_openni(monkeypatch, **setup)
    with pytest.raises(SourceError, match=match) as e:
        open_source("openni")
    _one_line(e)


def test_openni_source_reads_modes_units_intrinsics_and_times(monkeypatch):  # type: ignore[no-untyped-def]
    from depthtouch.sources.realsense import SourceDisconnected

    rng = np.random.default_rng(0)
    depth = [rng.integers(0, 40000, (240, 320), dtype=np.uint16) for _ in range(4)]
    stream = _fake_openni(monkeypatch, frames=depth)
    src = open_source("openni", resolution_wh="320x240")
    assert (src.resolution_wh, src.fps, src.depth_scale_m) == ((320, 240), 60.0, 0.001)
    assert stream.mode.pixelFormat == 100 and stream.started  # 1 mm preferred over 100 um
    assert src.K[0, 0] == pytest.approx(160 / np.tan(1.0225 / 2)) and src.K[0, 2] == 159.5
    got = []
    with pytest.raises(SourceDisconnected, match="no frame for 1 s"):
        for f in src.frames():
            got.append(f)
    assert [f.index for f in got] == [0, 1, 2, 3]
    assert all(np.array_equal(f.depth, d) for f, d in zip(got, depth, strict=True))
    np.testing.assert_allclose([f.timestamp_s for f in got], 1.0 + 0.033333 * np.arange(4))
    src.close()
    assert stream.stopped
    with pytest.raises(SourceError, match="no 1280x720 depth mode; choose one of 640x480, 320x240"):
        open_source("openni", resolution_wh=(1280, 720))


def test_find_redist_links_the_debian_layout(monkeypatch, tmp_path):  # type: ignore[no-untyped-def]
    from depthtouch.sources import openni as ni_mod

    lib = tmp_path / "lib"
    (lib / "OpenNI2" / "Drivers").mkdir(parents=True)
    (lib / "libOpenNI2.so.0").write_bytes(b"")
    monkeypatch.setattr(ni_mod, "SYSTEM_LIB_DIRS", (str(tmp_path / "none"), str(lib)))
    monkeypatch.delenv("OPENNI2_REDIST", raising=False)
    monkeypatch.setenv("OPENNI2_REDIST64", "/opt/vendor")
    dirs = ni_mod.find_redist("/my/redist", cache_dir=tmp_path / "cache")
    links = tmp_path / "cache" / "openni2"
    assert dirs == ["/my/redist", "/opt/vendor", str(links)]
    assert (links / "libOpenNI2.so").resolve() == (lib / "libOpenNI2.so.0").resolve()
    assert (links / "OpenNI2" / "Drivers").is_dir()
    assert ni_mod.find_redist(cache_dir=tmp_path / "cache")[-1] == str(links)  # idempotent


# --- the live RealSense source against a stand-in SDK (no camera here) -------------------------
@needs_rs
def test_the_sdk_has_every_name_the_live_source_uses():
    """Guards the stand-in below: the names it fakes exist in the real pyrealsense2."""
    for cls, names in [
        (rs.context, ["query_devices"]),
        (rs.device, ["get_info", "first_depth_sensor"]),
        (rs.sensor, ["get_stream_profiles", "supports", "set_option"]),
        (rs.depth_sensor, ["get_depth_scale"]),
        (rs.stream_profile, ["stream_type", "format", "as_video_stream_profile", "fps"]),
        (rs.video_stream_profile, ["width", "height", "get_intrinsics"]),
        (rs.config, ["enable_device", "enable_stream"]),
        (rs.pipeline, ["start", "stop", "try_wait_for_frames"]),
        (rs.pipeline_profile, ["get_device", "get_stream"]),
        (rs.composite_frame, ["get_depth_frame"]),
        (rs.frame, ["get_timestamp", "get_data"]),
    ]:
        for n in names:
            assert hasattr(cls, n), f"{cls.__name__}.{n}"
    assert rs.rs400_visual_preset.high_accuracy is not None
    assert rs.option.visual_preset is not None and rs.camera_info.serial_number is not None
    for f in ("spatial_filter", "temporal_filter", "hole_filling_filter"):
        assert hasattr(rs, f)


class _FakeRs:
    """Just enough of pyrealsense2 for RealSenseSource: one camera streaming a list of frames."""

    def __init__(self, modes, frames, *, preset_ok=True, devices=1,  # type: ignore[no-untyped-def]
                 query_error=False):
        import types

        self.stream = types.SimpleNamespace(depth="depth", color="color")
        self.format = types.SimpleNamespace(z16="z16", rgb8="rgb8")
        self.option = types.SimpleNamespace(visual_preset="visual_preset")
        self.camera_info = types.SimpleNamespace(serial_number="serial", name="name")
        self.rs400_visual_preset = types.SimpleNamespace(high_accuracy=3, default=1)
        self.set_options: list[tuple[str, float]] = []
        self.started: list[tuple] = []
        self.stopped = False
        fake = self
        outer_modes, outer_frames = modes, frames

        class Profile:
            def __init__(self, w, h, f, kind="depth", fmt="z16"):  # type: ignore[no-untyped-def]
                self.w, self.h, self.f, self.kind, self.fmt = w, h, f, kind, fmt

            def stream_type(self):  # type: ignore[no-untyped-def]
                return self.kind

            def format(self):  # type: ignore[no-untyped-def]
                return self.fmt

            def as_video_stream_profile(self):  # type: ignore[no-untyped-def]
                return self

            def width(self):  # type: ignore[no-untyped-def]
                return self.w

            def height(self):  # type: ignore[no-untyped-def]
                return self.h

            def fps(self):  # type: ignore[no-untyped-def]
                return self.f

            def get_intrinsics(self):  # type: ignore[no-untyped-def]
                return types.SimpleNamespace(fx=421.5, fy=422.0, ppx=self.w / 2, ppy=self.h / 2)

        class Sensor:
            def get_stream_profiles(self):  # type: ignore[no-untyped-def]
                return [Profile(*m) for m in outer_modes] + [Profile(640, 480, 30, "color", "rgb8")]

            def supports(self, opt):  # type: ignore[no-untyped-def]
                return True

            def set_option(self, opt, value):  # type: ignore[no-untyped-def]
                if not preset_ok:
                    raise RuntimeError("option not supported")
                fake.set_options.append((opt, value))

            def get_depth_scale(self):  # type: ignore[no-untyped-def]
                return np.float32(0.001).item()

        class Device:
            def get_info(self, what):  # type: ignore[no-untyped-def]
                return "f1234" if what == "serial" else "Intel RealSense D435"

            def first_depth_sensor(self):  # type: ignore[no-untyped-def]
                return Sensor()

        class Context:
            def query_devices(self):  # type: ignore[no-untyped-def]
                if query_error:
                    raise RuntimeError("failed to open usb interface: 0, error: RS2_USB_STATUS_ACCESS")
                return [Device() for _ in range(devices)]

        class Config:
            def enable_device(self, serial):  # type: ignore[no-untyped-def]
                self.serial = serial

            def enable_stream(self, *args):  # type: ignore[no-untyped-def]
                self.args = args

        class DepthFrame:
            def __init__(self, d, t_ms):  # type: ignore[no-untyped-def]
                self.d, self.t = d, t_ms

            def __bool__(self) -> bool:
                return True

            def get_timestamp(self):  # type: ignore[no-untyped-def]
                return self.t

            def get_data(self):  # type: ignore[no-untyped-def]
                return self.d

        class Pipeline:
            def __init__(self, ctx):  # type: ignore[no-untyped-def]
                self.i = 0

            def start(self, cfg):  # type: ignore[no-untyped-def]
                fake.started.append(cfg.args)
                _, w, h, _, f = cfg.args
                return types.SimpleNamespace(get_device=Device,
                                             get_stream=lambda s: Profile(w, h, f))

            def try_wait_for_frames(self, timeout_ms):  # type: ignore[no-untyped-def]
                if self.i >= len(outer_frames):
                    return False, None
                d, t = outer_frames[self.i]
                self.i += 1
                return True, types.SimpleNamespace(get_depth_frame=lambda: DepthFrame(d, t))

            def stop(self) -> None:
                fake.stopped = True

        self.context, self.config, self.pipeline = Context, Config, Pipeline
        self.filtered: list[str] = []

        def temporal_filter():  # type: ignore[no-untyped-def]
            def process(f):  # type: ignore[no-untyped-def]
                fake.filtered.append("temporal")
                return f
            return types.SimpleNamespace(process=process)

        self.temporal_filter = temporal_filter


D435 = [(848, 480, 90), (848, 480, 30), (640, 480, 30)]


def test_live_source_glue(monkeypatch):  # type: ignore[no-untyped-def]
    from depthtouch.sources.realsense import SourceDisconnected

    d = [np.full((480, 848), 1000 + i, np.uint16) for i in range(4)]
    frames = [(d[0], 5000.0), (d[1], 5011.1), (d[1], 5011.1), (d[2], 5022.2), (d[3], 5033.3)]
    fake = _FakeRs(D435, frames)
    monkeypatch.setitem(sys.modules, "pyrealsense2", fake)
    src = open_source("realsense")
    assert fake.started == [("depth", 848, 480, "z16", 90)]
    assert fake.set_options == [("visual_preset", 3.0)] and src.preset == "high_accuracy"
    assert src.name == "Intel RealSense D435 f1234" and src.fps == 90.0
    assert src.depth_scale_m == 0.001 and src.K[0, 0] == 421.5 and src.K[1, 2] == 240.0
    got = []
    with pytest.raises(SourceDisconnected, match="no frame for 1 s; check the USB cable"):
        for f in src.frames():
            got.append(f)
    assert [f.index for f in got] == [0, 1, 2, 3]  # the repeated frame is skipped
    np.testing.assert_allclose([f.timestamp_s for f in got], [5.0, 5.0111, 5.0222, 5.0333])
    assert [int(f.depth[0, 0]) for f in got] == [1000, 1001, 1002, 1003]
    src.close()
    assert fake.stopped and fake.filtered == []  # no SDK post-processing unless asked for


def test_live_source_post_processing_when_asked(monkeypatch):  # type: ignore[no-untyped-def]
    d = np.zeros((480, 848), np.uint16)
    fake = _FakeRs(D435, [(d, 1.0), (d, 2.0)])
    monkeypatch.setitem(sys.modules, "pyrealsense2", fake)
    src = RealSenseSource(post_processing=["temporal"], frame_timeout_s=0.01)
    with pytest.raises(SourceError):
        list(src.frames())
    assert fake.filtered == ["temporal", "temporal"]


@pytest.mark.parametrize(
    ("kwargs", "fake_kw", "want"),
    [
        ({"fps": 30}, {}, ("depth", 848, 480, "z16", 30)),
        ({"resolution_wh": "640x480"}, {}, ("depth", 640, 480, "z16", 30)),
        ({"preset": None}, {}, ("depth", 848, 480, "z16", 90)),
        ({}, {"preset_ok": False}, ("depth", 848, 480, "z16", 90)),  # preset not offered
        ({"serial": "999"}, {}, "no RealSense camera with serial 999; connected: f1234"),
        ({"fps": 60}, {}, "no 60 fps at 848x480; choose one of 90, 30"),
        ({}, {"query_error": True}, "cannot use the RealSense camera .*RS2_USB_STATUS_ACCESS.*udev"),
        ({}, {"devices": 0}, "no RealSense camera found"),
    ],
)
def test_live_source_options(monkeypatch, kwargs, fake_kw, want):  # type: ignore[no-untyped-def]
    fake = _FakeRs(D435, [], **fake_kw)
    monkeypatch.setitem(sys.modules, "pyrealsense2", fake)
    if isinstance(want, str):
        with pytest.raises(SourceError, match=want):
            RealSenseSource(**kwargs)
        return
    src = RealSenseSource(**kwargs)
    assert fake.started == [want]
    assert (src.preset is None) == (kwargs.get("preset", "x") is None or not
                                     fake_kw.get("preset_ok", True))


@needs_rs
def test_replay_command_reads_db3(tmp_path):  # type: ignore[no-untyped-def]
    import json

    from depthtouch.cli import main

    depth, ts = _scene()
    db3 = write_realsense_recording(tmp_path / "s.db3", depth, ts, 0.001, K_CROP)
    out = tmp_path / "ev.jsonl"
    assert main(["replay", str(db3), "--events", str(out), "-q"]) == 0
    states = [json.loads(x)["state"] for x in out.read_text().splitlines()]
    assert states.count("down") == 2 and states.count("up") == 2
