"""Intel RealSense: live cameras, recordings (``.bag``/``.db3``) and a recording writer.

Everything goes through ``pyrealsense2`` (the ``realsense`` extra), imported only when a
RealSense source is opened, so the rest of the package works without it.

- :class:`RealSenseSource` streams depth from a camera: 848x480 at 90 fps when the model has it
  (else 30), the "high accuracy" visual preset, the SDK's host-side post-processing off unless
  asked for, depth units and intrinsics read from the device, timestamps from the device.
- :class:`RealSensePlaybackSource` reads a recording through the SDK at full speed (not real
  time), every frame, without a camera.
- Writing recordings the SDK can play: :mod:`depthtouch.sources.realsense_record`.
"""

from __future__ import annotations

import contextlib
import queue
import threading
from collections.abc import Iterable, Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import SourceError
from ..types import Frame
from .base import SourceBase, validate_depth_scale, validate_K

INSTALL_HINT = "pip install 'depthtouch[realsense]'"

#: Resolutions tried in order when none is asked for: 848x480 is the D4xx's native depth
#: resolution (best precision per pixel at the highest frame rates).
PREFERRED_RESOLUTIONS_WH: tuple[tuple[int, int], ...] = ((848, 480), (640, 480), (1280, 720))
#: Frame rates tried in order when none is asked for: 90 Hz halves the touch-down latency.
PREFERRED_FPS: tuple[int, ...] = (90, 30)
#: Host-side SDK filters that keep the resolution (decimation is left out on purpose).
POST_PROCESSING_FILTERS = ("spatial", "temporal", "hole_filling")
#: Names of ``rs.rs400_visual_preset`` accepted for ``preset``.
VISUAL_PRESETS = ("high_accuracy", "default", "high_density", "medium_density", "hand")


class SourceDisconnected(SourceError):
    """A live camera stopped delivering frames (unplugged, USB reset); the live loop reopens it."""


def import_pyrealsense2() -> Any:
    """The ``pyrealsense2`` module, or SourceError with the install hint (one line)."""
    try:
        import pyrealsense2 as rs
    except ImportError as e:
        text = str(e)
        if "libusb" in text:
            raise SourceError(
                f"pyrealsense2 cannot load libusb ({text}); install it: apt-get install "
                "libusb-1.0-0 (Linux) or brew install libusb (macOS)"
            ) from e
        raise SourceError(
            f"pyrealsense2 is not installed; install the RealSense extra: {INSTALL_HINT}"
        ) from e
    return rs


def _first_line(e: BaseException) -> str:
    text = str(e).strip()
    return text.splitlines()[0] if text else type(e).__name__


def choose_depth_mode(
    available: Iterable[tuple[int, int, int]],
    resolution_wh: tuple[int, int] | None = None,
    fps: int | None = None,
) -> tuple[int, int, int]:
    """Pick (width, height, fps) among the camera's Z16 depth modes.

    available: (width, height, fps) triples the camera offers.
    resolution_wh: wanted resolution, or None for the first of :data:`PREFERRED_RESOLUTIONS_WH`
        the camera has (else its widest mode).
    fps: wanted frame rate, or None for 90 where the model allows, else 30, else its fastest.
    Raises SourceError naming what the camera offers when the wish cannot be met.
    """
    modes = sorted({(int(w), int(h), int(f)) for w, h, f in available})
    if not modes:
        raise SourceError("the camera offers no Z16 depth mode; update its firmware")
    sizes = sorted({(w, h) for w, h, _ in modes}, key=lambda s: (-s[0] * s[1], s))
    if resolution_wh is not None:
        size = (int(resolution_wh[0]), int(resolution_wh[1]))
        if size not in sizes:
            offer = ", ".join(f"{w}x{h}" for w, h in sizes)
            raise SourceError(
                f"the camera has no {size[0]}x{size[1]} depth mode; choose one of {offer}"
            )
    else:
        size = next((s for s in PREFERRED_RESOLUTIONS_WH if s in sizes), sizes[0])
    rates = sorted({f for w, h, f in modes if (w, h) == size}, reverse=True)
    if fps is not None:
        if int(fps) not in rates:
            offer = ", ".join(str(r) for r in rates)
            raise SourceError(
                f"the camera has no {fps} fps at {size[0]}x{size[1]}; choose one of {offer}"
            )
        rate = int(fps)
    else:
        rate = next((r for r in PREFERRED_FPS if r in rates), rates[0])
    return size[0], size[1], rate


def intrinsics_to_K(intr: Any) -> np.ndarray:
    """A (3, 3) float64 pinhole matrix from an ``rs.intrinsics`` (fx, fy, ppx, ppy)."""
    return np.array(
        [[float(intr.fx), 0.0, float(intr.ppx)], [0.0, float(intr.fy), float(intr.ppy)],
         [0.0, 0.0, 1.0]],
        dtype=np.float64,
    )


def _clean_scale(value: float) -> float:
    # The SDK stores depth units as float32: 0.001 comes back as 0.0010000000475; keep the
    # decimal the device meant (7 significant digits is float32's precision).
    return float(f"{float(value):.7g}")


def parse_resolution(value: str | tuple[int, int] | None) -> tuple[int, int] | None:
    if value is None or isinstance(value, tuple):
        return value
    w, sep, h = str(value).lower().partition("x")
    if not sep or not w.isdigit() or not h.isdigit():
        raise SourceError(f"resolution {value!r} is not WIDTHxHEIGHT; give e.g. 848x480")
    return int(w), int(h)


def _check_filters(names: Sequence[str]) -> tuple[str, ...]:
    out = tuple(str(n).strip() for n in names if str(n).strip())
    for n in out:
        if n not in POST_PROCESSING_FILTERS:
            raise SourceError(
                f"unknown post-processing filter {n!r}; use any of "
                f"{', '.join(POST_PROCESSING_FILTERS)}"
            )
    return out


def _make_filters(rs: Any, names: Sequence[str]) -> list[Any]:
    classes = {"spatial": "spatial_filter", "temporal": "temporal_filter",
               "hole_filling": "hole_filling_filter"}
    return [getattr(rs, classes[n])() for n in names]


class RealSenseSource(SourceBase):
    """Depth frames from a connected RealSense camera.

    serial: the camera's serial number, or None for the first one found.
    resolution_wh: (width, height) or "WxH"; default 848x480 where available (see
        :func:`choose_depth_mode`).
    fps: frames per second; default 90 where the mode allows, else 30.
    preset: visual preset name (default "high_accuracy"; None leaves the camera's setting).
    post_processing: names from :data:`POST_PROCESSING_FILTERS` to apply on the host, in that
        order; default none (filters add latency and smear fingertips).
    frame_timeout_s: a gap without frames longer than this raises :class:`SourceDisconnected`
        (default 1.0 s; the first frame may take up to ``start_timeout_s``, default 5.0 s).

    Timestamps are the device's (seconds; hardware or host-synchronised global time). The
    camera is opened in the constructor (SourceError when there is none) and streams until
    :meth:`close`.
    """

    def __init__(
        self,
        serial: str | None = None,
        *,
        resolution_wh: tuple[int, int] | str | None = None,
        fps: int | None = None,
        preset: str | None = "high_accuracy",
        post_processing: Sequence[str] = (),
        frame_timeout_s: float = 1.0,
        start_timeout_s: float = 5.0,
    ) -> None:
        if preset is not None and preset not in VISUAL_PRESETS:
            raise SourceError(
                f"unknown RealSense preset {preset!r}; use one of {', '.join(VISUAL_PRESETS)}"
            )
        if not frame_timeout_s > 0 or not start_timeout_s > 0:
            raise SourceError("frame_timeout_s and start_timeout_s must be > 0 seconds")
        wanted_wh = parse_resolution(resolution_wh)
        self._filter_names = _check_filters(post_processing)
        rs = import_pyrealsense2()
        self._rs = rs
        self.frame_timeout_s = float(frame_timeout_s)
        self.start_timeout_s = float(start_timeout_s)
        self._pipe: Any = None
        try:
            self._open(rs, serial, wanted_wh, fps, preset)
        except RuntimeError as e:  # the SDK's errors: permissions, a camera that vanished
            self.close()
            raise SourceError(
                f"cannot use the RealSense camera ({_first_line(e)}); replug it, and on Linux "
                "install librealsense's udev rules (99-realsense-libusb.rules)"
            ) from e
        except SourceError:
            self.close()
            raise
        self._filters = _make_filters(rs, self._filter_names)

    def _open(self, rs: Any, serial: str | None, wanted_wh: tuple[int, int] | None,
              fps: int | None, preset: str | None) -> None:
        ctx = rs.context()
        devices = list(ctx.query_devices())
        if not devices:
            raise SourceError(
                "no RealSense camera found; connect one to a USB 3 port, or replay a "
                "recording: depthtouch replay FILE.db3"
            )
        serials = [d.get_info(rs.camera_info.serial_number) for d in devices]
        if serial is not None and serial not in serials:
            raise SourceError(
                f"no RealSense camera with serial {serial}; connected: {', '.join(serials)}"
            )
        dev = devices[serials.index(serial) if serial is not None else 0]
        self.serial = dev.get_info(rs.camera_info.serial_number)
        model = dev.get_info(rs.camera_info.name)
        sensor = dev.first_depth_sensor()
        modes = []
        for p in sensor.get_stream_profiles():
            if p.stream_type() == rs.stream.depth and p.format() == rs.format.z16:
                vp = p.as_video_stream_profile()
                modes.append((vp.width(), vp.height(), vp.fps()))
        w, h, rate = choose_depth_mode(modes, wanted_wh, fps)
        self.name = f"{model} {self.serial}"
        cfg = rs.config()
        cfg.enable_device(self.serial)
        cfg.enable_stream(rs.stream.depth, w, h, rs.format.z16, rate)
        pipe = rs.pipeline(ctx)
        try:
            profile = pipe.start(cfg)
        except RuntimeError as e:
            raise SourceError(
                f"{self.name}: cannot start depth {w}x{h}@{rate} ({_first_line(e)}); close "
                "other programs using the camera or replug it"
            ) from e
        self._pipe = pipe
        depth_sensor = profile.get_device().first_depth_sensor()
        self.preset = None
        if preset is not None and depth_sensor.supports(rs.option.visual_preset):
            try:
                depth_sensor.set_option(
                    rs.option.visual_preset, float(int(getattr(rs.rs400_visual_preset, preset)))
                )
                self.preset = preset
            except (RuntimeError, AttributeError):
                self.preset = None  # not offered by this model; keep the camera's own
        self.depth_scale_m = validate_depth_scale(
            _clean_scale(depth_sensor.get_depth_scale()), self.name
        )
        vsp = profile.get_stream(rs.stream.depth).as_video_stream_profile()
        self.K = validate_K(intrinsics_to_K(vsp.get_intrinsics()), self.name)
        self.resolution_wh = (w, h)
        self.fps = float(rate)

    def frames(self) -> Iterator[Frame]:
        """Frames until :meth:`close`; :class:`SourceDisconnected` when the camera goes silent."""
        pipe = self._pipe
        if pipe is None:
            raise SourceError(f"{self.name}: the camera is closed; open a new source")
        index = 0
        last_t: float | None = None
        while self._pipe is not None:
            timeout_s = self.start_timeout_s if index == 0 else self.frame_timeout_s
            try:
                ok, fs = pipe.try_wait_for_frames(int(timeout_s * 1000))
            except RuntimeError as e:
                raise SourceDisconnected(
                    f"{self.name}: camera stopped ({_first_line(e)}); check the USB cable"
                ) from e
            if not ok:
                if self._pipe is None:
                    return
                raise SourceDisconnected(
                    f"{self.name}: no frame for {timeout_s:g} s; check the USB cable and power"
                )
            depth = fs.get_depth_frame()
            if not depth:
                continue
            for f in self._filters:
                depth = f.process(depth)
            t = float(depth.get_timestamp()) / 1000.0
            if last_t is not None and t <= last_t:
                continue  # a repeated frame (USB hiccup); time must increase
            last_t = t
            arr = np.array(np.asanyarray(depth.get_data()), dtype=np.uint16, copy=True)
            yield Frame(arr, t, index, self.depth_scale_m, self.K)
            index += 1

    def close(self) -> None:
        pipe, self._pipe = self._pipe, None
        if pipe is not None:
            with contextlib.suppress(RuntimeError):
                pipe.stop()


class RealSensePlaybackSource(SourceBase):
    """Every depth frame of a RealSense recording (``.bag`` or ``.db3``), as fast as read.

    path: the recording. The file is played through the SDK in non-real-time mode straight from
    its depth sensor (no ``rs.pipeline``, whose queue drops frames when the file was recorded
    faster than it is read); a small bounded queue gives back-pressure, so no frame is lost.
    Timestamps are the recorded ones (seconds); frame indices count from 0. ``frames()`` may be
    called again to start over.
    """

    def __init__(self, path: str | Path, *, queue_size: int = 4) -> None:
        p = Path(path)
        self.name = str(p)
        self.path = p
        if not p.is_file():
            raise SourceError(f"{p}: no such file; check the recording path")
        if queue_size < 1:
            raise SourceError(f"queue_size = {queue_size} must be at least 1")
        self._rs = import_pyrealsense2()
        self._queue_size = int(queue_size)
        self._closing = threading.Event()
        self._sensor: Any = None
        self._playback: Any = None
        sensor, profile, _ = self._load()
        try:
            scale = sensor.as_depth_sensor().get_depth_scale()
        except RuntimeError:
            scale = 0.001  # recordings without depth units were made in millimetres
        self.depth_scale_m = validate_depth_scale(_clean_scale(scale), self.name)
        try:
            self.K = validate_K(intrinsics_to_K(profile.get_intrinsics()), self.name)
        except (RuntimeError, SourceError):
            self.K = None  # a recording without calibration: pixel units only
        self.resolution_wh = (int(profile.width()), int(profile.height()))
        self.fps = float(profile.fps()) if profile.fps() > 0 else None

    def _load(self) -> tuple[Any, Any, Any]:
        """(depth sensor, its Z16 video profile, playback) of a freshly loaded file."""
        rs = self._rs
        try:
            dev = rs.context().load_device(str(self.path))
            playback = dev.as_playback()
            playback.set_real_time(False)
            for sensor in dev.query_sensors():
                for prof in sensor.get_stream_profiles():
                    if prof.stream_type() == rs.stream.depth and prof.format() == rs.format.z16:
                        return sensor, prof.as_video_stream_profile(), playback
        except RuntimeError as e:
            raise SourceError(
                f"{self.path}: not a readable RealSense recording ({_first_line(e)}); record "
                "one with depthtouch record"
            ) from e
        raise SourceError(f"{self.path}: the recording has no Z16 depth stream; record depth")

    def frames(self) -> Iterator[Frame]:
        self._stop()
        rs = self._rs
        sensor, profile, playback = self._load()
        q: queue.Queue[tuple[float, np.ndarray]] = queue.Queue(maxsize=self._queue_size)
        closing = threading.Event()
        self._closing = closing

        def on_frame(f: Any) -> None:  # the SDK's playback thread; blocking = back-pressure
            item = (float(f.get_timestamp()) / 1000.0,
                    np.array(np.asanyarray(f.get_data()), dtype=np.uint16, copy=True))
            while not closing.is_set():
                try:
                    q.put(item, timeout=0.1)
                    return
                except queue.Full:
                    continue

        try:
            sensor.open(profile)
            sensor.start(on_frame)
        except RuntimeError as e:
            raise SourceError(f"{self.path}: cannot play the recording ({_first_line(e)})") from e
        self._sensor, self._playback = sensor, playback
        index = 0
        last_t: float | None = None
        idle_s = 0.0
        try:
            while True:
                try:
                    t, arr = q.get(timeout=0.1)
                except queue.Empty:
                    if playback.current_status() == rs.playback_status.stopped and q.empty():
                        return
                    idle_s += 0.1
                    if idle_s > 10.0:
                        raise SourceError(
                            f"{self.path}: playback stalled for 10 s; the file may be truncated"
                        ) from None
                    continue
                idle_s = 0.0
                if last_t is not None and t <= last_t:
                    continue  # recorded duplicates; time must increase
                last_t = t
                yield Frame(arr, t, index, self.depth_scale_m, self.K)
                index += 1
        finally:
            self._stop()

    def _stop(self) -> None:
        sensor, self._sensor = self._sensor, None
        self._playback = None
        self._closing.set()
        if sensor is not None:
            with contextlib.suppress(RuntimeError):
                sensor.stop()
            with contextlib.suppress(RuntimeError):
                sensor.close()

    def close(self) -> None:
        self._stop()
