"""OpenNI 2 depth cameras (Orbbec Astra, Asus Xtion, PrimeSense, Kinect v1 through its driver).

Uses the ``openni`` package (the ``openni`` extra; a ctypes wrapper, imported only when an
OpenNI source is opened) and the OpenNI 2 runtime (``libOpenNI2.so`` with its ``OpenNI2/Drivers``
folder; Debian/Ubuntu: ``apt-get install libopenni2-0``, Orbbec ships its own). ``openni:URI``
opens a given device, or an ``.oni`` recording when URI is a file.

The wrapper wants ``libOpenNI2.so`` (without a version suffix) in one folder beside
``OpenNI2/Drivers``; the Debian package installs ``libOpenNI2.so.0``, so when only that is found a
folder of two links is made under ``~/.cache/depthtouch/openni2`` and used.
"""

from __future__ import annotations

import contextlib
import math
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import SourceError
from ..types import Frame
from .base import SourceBase, validate_K
from .realsense import SourceDisconnected, choose_depth_mode, parse_resolution

INSTALL_HINT = "pip install 'depthtouch[openni]'"
RUNTIME_HINT = ("install the OpenNI 2 runtime (apt-get install libopenni2-0, or your camera "
                "vendor's SDK) or set OPENNI2_REDIST to the folder with libOpenNI2.so")
#: Folders searched for the OpenNI 2 runtime, after ``redist`` and $OPENNI2_REDIST(64).
SYSTEM_LIB_DIRS = ("/usr/lib/x86_64-linux-gnu", "/usr/lib/aarch64-linux-gnu",
                   "/usr/lib/arm-linux-gnueabihf", "/usr/local/lib", "/usr/lib", "/lib")
#: OpenNI pixel formats (OniPixelFormat) and their metres per unit.
PIXEL_FORMAT_SCALES_M = {100: 0.001, 101: 0.0001}  # DEPTH_1_MM, DEPTH_100_UM


def import_openni2() -> Any:
    """The ``openni.openni2`` module, or SourceError with the install hint (one line)."""
    try:
        from openni import openni2
    except ImportError as e:
        raise SourceError(f"the openni package is not installed; {INSTALL_HINT}") from e
    except Exception as e:  # openni 2.3 fails to define its enums on Python >= 3.13
        raise SourceError(
            f"the openni package cannot load on this Python ({type(e).__name__}: {e}); use "
            "Python <= 3.12 for OpenNI cameras"
        ) from e
    return openni2


def find_redist(redist: str | Path | None = None, *, cache_dir: Path | None = None) -> list[str]:
    """Folders to hand to ``openni2.initialize``, best first.

    redist: a folder given by the user (kept first). Then $OPENNI2_REDIST64 / $OPENNI2_REDIST,
    then system folders holding ``libOpenNI2.so``; a system ``libOpenNI2.so.0`` with an
    ``OpenNI2`` drivers folder beside it gets a link folder in ``cache_dir``.
    """
    out: list[str] = []
    if redist is not None:
        out.append(str(redist))
    for var in ("OPENNI2_REDIST64", "OPENNI2_REDIST"):
        if os.environ.get(var):
            out.append(os.environ[var])
    for d in SYSTEM_LIB_DIRS:
        lib_dir = Path(d)
        if (lib_dir / "libOpenNI2.so").is_file():
            out.append(str(lib_dir))
        elif (lib_dir / "libOpenNI2.so.0").is_file() and (lib_dir / "OpenNI2").is_dir():
            links = (cache_dir or Path.home() / ".cache" / "depthtouch") / "openni2"
            try:
                links.mkdir(parents=True, exist_ok=True)
                for name, target in (("libOpenNI2.so", lib_dir / "libOpenNI2.so.0"),
                                     ("OpenNI2", lib_dir / "OpenNI2")):
                    link = links / name
                    if not link.is_symlink() or Path(os.readlink(link)) != target:
                        link.unlink(missing_ok=True)
                        link.symlink_to(target)
                out.append(str(links))
            except OSError:
                continue  # a read-only home: try the other folders
    return list(dict.fromkeys(out))


def K_from_fov(resolution_wh: tuple[int, int], hfov_rad: float, vfov_rad: float) -> np.ndarray:
    """Pinhole K (3, 3) from the field of view (radians); principal point at the centre."""
    w, h = resolution_wh
    if not (0 < hfov_rad < math.pi and 0 < vfov_rad < math.pi):
        raise SourceError(f"field of view {hfov_rad:.3f} x {vfov_rad:.3f} rad is not in (0, pi)")
    fx = (w / 2.0) / math.tan(hfov_rad / 2.0)
    fy = (h / 2.0) / math.tan(vfov_rad / 2.0)
    return np.array([[fx, 0.0, (w - 1) / 2.0], [0.0, fy, (h - 1) / 2.0], [0.0, 0.0, 1.0]])


def _int(v: Any) -> int:
    return int(getattr(v, "value", v))


class OpenNISource(SourceBase):
    """Depth frames from an OpenNI 2 device.

    uri: device URI (or an ``.oni`` file), None for the first device.
    resolution_wh / fps: wanted mode (default 640x480 at 30 on most devices; see
        :func:`~depthtouch.sources.realsense.choose_depth_mode`).
    redist: folder with ``libOpenNI2.so`` when not found automatically (see :func:`find_redist`).
    frame_timeout_s: a gap longer than this raises :class:`SourceDisconnected` (default 1.0 s;
        the first frame may take ``start_timeout_s``, default 5.0 s).

    Depth units come from the pixel format (1 mm or 100 um); K from the reported field of view;
    timestamps from the device (microseconds -> seconds).
    """

    def __init__(
        self,
        uri: str | None = None,
        *,
        resolution_wh: tuple[int, int] | str | None = None,
        fps: int | None = None,
        redist: str | Path | None = None,
        frame_timeout_s: float = 1.0,
        start_timeout_s: float = 5.0,
    ) -> None:
        if not frame_timeout_s > 0 or not start_timeout_s > 0:
            raise SourceError("frame_timeout_s and start_timeout_s must be > 0 seconds")
        wanted_wh = parse_resolution(resolution_wh)
        openni2 = import_openni2()
        self._ni = openni2
        self.frame_timeout_s, self.start_timeout_s = float(frame_timeout_s), float(start_timeout_s)
        self._device: Any = None
        self._stream: Any = None
        dirs = find_redist(redist)
        try:
            openni2.initialize(dirs or ["."])
        except Exception as e:  # InitializationError / OSError from ctypes
            raise SourceError(f"the OpenNI 2 runtime cannot be loaded; {RUNTIME_HINT}") from e
        try:
            self._device = (openni2.Device.open_any() if uri is None
                            else openni2.Device.open_file(uri.encode()))
        except Exception as e:  # OpenNIError: no device, busy, no permission
            where = f"at {uri}" if uri else "connected"
            raise SourceError(
                f"no OpenNI device {where} ({str(e).strip().splitlines()[0] if str(e) else e!r}); "
                "plug the camera in, check its udev rules, or use openni:URI"
            ) from e
        self.name = f"openni:{uri}" if uri else "openni"
        try:
            stream = self._device.create_depth_stream()
            if stream is None:
                raise SourceError(f"{self.name}: the device has no depth sensor")
            modes = [m for m in stream.get_sensor_info().videoModes
                     if _int(m.pixelFormat) in PIXEL_FORMAT_SCALES_M]
            w, h, rate = choose_depth_mode(
                [(_int(m.resolutionX), _int(m.resolutionY), _int(m.fps)) for m in modes],
                wanted_wh, fps)
            mode = next(m for m in sorted(modes, key=lambda m: _int(m.pixelFormat))
                        if (_int(m.resolutionX), _int(m.resolutionY), _int(m.fps)) == (w, h, rate))
            stream.set_video_mode(mode)
            stream.start()
            self._stream = stream
            self.depth_scale_m = PIXEL_FORMAT_SCALES_M[_int(mode.pixelFormat)]
            self.resolution_wh = (w, h)
            self.fps = float(rate)
            try:
                self.K = validate_K(K_from_fov((w, h), float(stream.get_horizontal_fov()),
                                               float(stream.get_vertical_fov())), self.name)
            except SourceError:
                self.K = None
        except SourceError:
            self.close()
            raise
        except Exception as e:
            self.close()
            raise SourceError(f"{self.name}: cannot start the depth stream ({e}); replug it") from e

    def frames(self) -> Iterator[Frame]:
        stream, ni = self._stream, self._ni
        if stream is None:
            raise SourceError(f"{self.name}: the camera is closed; open a new source")
        index = 0
        last_t: float | None = None
        w, h = self.resolution_wh
        while self._stream is not None:
            timeout = self.start_timeout_s if index == 0 else self.frame_timeout_s
            try:
                ready = ni.wait_for_any_stream([stream], timeout)
                if ready is None:
                    if self._stream is None:
                        return
                    raise SourceDisconnected(
                        f"{self.name}: no frame for {timeout:g} s; check the USB cable and power")
                f = stream.read_frame()
                buf = np.frombuffer(f.get_buffer_as_uint16(), dtype=np.uint16)
                t = float(_int(f.timestamp)) / 1e6
                fw, fh = _int(f.width), _int(f.height)
            except SourceDisconnected:
                raise
            except Exception as e:  # OpenNIError from a vanished device
                raise SourceDisconnected(f"{self.name}: camera stopped ({e}); replug it") from e
            if (fw, fh) != (w, h) or buf.size != w * h:
                continue  # a mode switch in flight; the stream settles on the set mode
            if last_t is not None and t <= last_t:
                continue
            last_t = t
            yield Frame(buf.reshape(h, w).copy(), t, index, self.depth_scale_m, self.K)
            index += 1

    def close(self) -> None:
        stream, self._stream = self._stream, None
        device, self._device = self._device, None
        if stream is not None:
            with contextlib.suppress(Exception):
                stream.stop()
            with contextlib.suppress(Exception):
                stream.close()
        if device is not None:
            with contextlib.suppress(Exception):
                device.close()
