"""The web page wired to a pipeline, for ``depthtouch serve`` and ``depthtouch run --serve``.

:class:`WebPage` starts a :class:`~depthtouch.web.server.WebServer` and gives the loop its sinks:
the WebSocket stream of every frame's events and status, and a few height maps per second (only
while a page is connected). A calibration fitted on the page goes to the pipeline, which maps
the events with it from the next frame on.

``serve`` runs the one loop (:func:`depthtouch.driver.drive`) in a background thread: it paces
recordings and the simulator at their own timestamps (so a person can watch) and starts a
finished recording again (the surface is learned again, the page is told to clear its trails),
or, with ``loop=False``, ends with a message on the page.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

from ..driver import DriveStats, Pacer, drive
from ..errors import DepthTouchError, OutputError
from ..outputs.base import Sink
from ..sources.base import DepthSource
from ..types import FrameResult
from .cameras import CameraView
from .server import WebServer


class _Heights:
    """A sink: the height maps of the frames, when due."""

    def __init__(self, server: WebServer) -> None:
        self.server = server

    def send(self, result: FrameResult) -> None:
        self.server.send_height(result)

    def close(self) -> None:
        """Nothing to release: the page's owner stops the server."""


@runtime_checkable
class CameraSet(Protocol):
    """What the page needs of several cameras (:class:`depthtouch.multicam.MultiPipeline`)."""

    resolutions: list[tuple[int, int] | None]
    views_version: int

    @property
    def calibrations(self) -> list[Any]: ...

    def set_camera_calibration(self, cam: int, calibration: Any) -> None: ...


class _CameraViews:
    """A sink: tells the page each camera's part of the screen whenever one changes (a
    camera's first frame, a new calibration)."""

    def __init__(self, server: WebServer, cameras: CameraSet, names: Sequence[str]) -> None:
        self.server, self.cameras, self.names = server, cameras, list(names)
        self._version: int | None = None

    def send(self, result: FrameResult) -> None:
        if self.cameras.views_version != self._version:
            self.publish()

    def publish(self) -> None:
        c = self.cameras
        self._version = c.views_version
        cals = c.calibrations
        views = [CameraView(k, self.names[k] if k < len(self.names) else f"camera {k}",
                            c.resolutions[k], cals[k]) for k in range(len(cals))]
        self.server.set_cameras(views, tuple(cals[0].screen_wh))

    def close(self) -> None:
        """Nothing to release."""


def page_sinks(server: WebServer) -> list[Sink]:
    """The sinks that feed a server's page: the WebSocket stream and the height maps."""
    return [server.sink, _Heights(server)]


class WebPage:
    """The web page of a running sensor: a context manager that starts and stops the server.

    address: "HOST:PORT" (see :func:`depthtouch.checks.parse_address`; port 0 = any free one)
        or (host, port).
    pipeline: gets the page's calibration (``set_calibration``); its own calibration is shown.
        Several cameras (a :class:`CameraSet`, e.g. a MultiPipeline): the page shows each
        camera's part of the screen and calibrates one camera at a time
        (``set_camera_calibration``), named by ``camera_names`` (default "camera K").
    server_options: more keywords for :class:`WebServer` (calibration_out, allowed_origins...).
    """

    def __init__(self, address: str | tuple[str, int], pipeline: Any, *, source_name: str = "",
                 camera_names: Sequence[str] = (), **server_options: Any) -> None:
        from ..checks import parse_address

        host, port = address if isinstance(address, tuple) else parse_address(
            address, what="web address", default_port=8765, default_host="127.0.0.1",
            allow_port_zero=True)
        self.server = WebServer(host, port, calibration=pipeline.calibration,
                                source_name=source_name, **server_options)
        self.sinks = page_sinks(self.server)
        if isinstance(pipeline, CameraSet):
            self.server.on_camera_calibration = pipeline.set_camera_calibration
            views = _CameraViews(self.server, pipeline, camera_names)
            views.publish()  # before the first frame: no parts yet, targets on the whole screen
            self.sinks.append(views)
        else:
            self.server.on_calibration = pipeline.set_calibration

    @property
    def url(self) -> str:
        return self.server.url

    def __enter__(self) -> WebPage:
        self.server.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.server.stop()


@dataclass
class LoopStats:
    """Counters of a serve run: frames processed, events sent, passes over the source."""

    frames: int = 0
    events: int = 0
    passes: int = 0


class SourceLoop:
    """Source -> pipeline -> web page, in a background thread, pass after pass.

    open_source: returns a fresh source (called again for each pass unless ``reuse_source``).
    pipeline: a :class:`~depthtouch.pipeline.Pipeline`.
    page: the :class:`WebPage` (or anything with ``server`` and ``sinks``).
    realtime: play at the frames' own pace (default True); False as fast as possible.
    loop: start a finished recording again (default True); False stops after one pass.
    max_passes: stop after this many passes even when looping (None = never).
    reuse_source: iterate the same source again for each pass (recordings in memory and the
        simulator, which renders its scene when opened).

    A DepthTouchError from the source or the pipeline stops the loop and is kept in ``error``
    (re-raised by :meth:`join`); :meth:`stop` ends it at the next frame.
    """

    def __init__(self, open_source: Callable[[], DepthSource], pipeline: Any, page: Any, *,
                 realtime: bool = True, loop: bool = True, max_passes: int | None = None,
                 reuse_source: bool = False) -> None:
        self.open_source, self.pipeline, self.page = open_source, pipeline, page
        self.realtime, self.loop, self.max_passes = realtime, loop, max_passes
        self.reuse_source = reuse_source
        self.stats = LoopStats()
        self.error: BaseException | None = None
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self) -> SourceLoop:
        self._thread = threading.Thread(target=self._run, name="depthtouch-source", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def join(self, timeout_s: float | None = None, *, raise_error: bool = True) -> bool:
        """Wait for the loop to end; True when it ended. Re-raises the loop's error."""
        if self._thread is not None:
            self._thread.join(timeout_s)
            if self._thread.is_alive():
                return False
        if raise_error and self.error is not None:
            raise self.error
        return True

    def _run(self) -> None:
        server = self.page.server
        source: DepthSource | None = None
        try:
            while not self._stop.is_set():
                if source is None:
                    source = self.open_source()
                pace = Pacer(1.0, wait=self._stop.wait) if self.realtime else None
                stats = drive(source, self.pipeline, self.page.sinks, pace=pace, stop=self._stop)
                self._count(stats, source)
                if not self.reuse_source:
                    source.close()
                    source = None
                if self._stop.is_set():
                    break
                if not self.loop or (self.max_passes is not None
                                     and self.stats.passes >= self.max_passes):
                    server.notify({"type": "info", "message": "the recording has finished"})
                    break
                self.pipeline.reset()
                server.sink.reset()
                server.notify({"type": "reset", "message": "the recording starts again"})
        except DepthTouchError as e:
            self.error = e
            server.notify({"type": "info", "message": f"stopped: {e}"})
        except BaseException as e:  # a bug: keep it for join() to re-raise with its traceback
            self.error = e
        finally:
            if source is not None:
                source.close()

    def _count(self, stats: DriveStats, source: DepthSource) -> None:
        if stats.frames == 0 and not self._stop.is_set():
            raise OutputError(f"{getattr(source, 'name', 'the source')} gave no frames; "
                              "check the recording")
        self.stats.frames += stats.frames
        self.stats.events += stats.events
        self.stats.passes += 1


def run_serve(
    source_spec: str,
    *,
    host: str = "127.0.0.1",
    port: int = 8765,
    config_path: str | None = None,
    calibration_path: str | None = None,
    calibration_out: str = "calibration.json",
    realtime: bool = True,
    loop: bool = True,
    surface_frames: int | None = None,
    allowed_origins: Sequence[str] = (),
    announce: Callable[[str], None] = print,
) -> LoopStats:
    """Serve the page for a source until Ctrl-C, or until a recording ends with ``loop=False``.

    Live cameras (``realsense``, ``openni``) are never paced: they deliver frames in real time.
    Errors (bad source, port taken, bad calibration file) raise DepthTouchError subclasses.
    allowed_origins: browser origins besides the page's own allowed on the WebSocket
    (``serve --allow-origin``), e.g. ``http://localhost:5173``.
    """
    from ..calibration import load_calibration
    from ..config import PipelineConfig, load_config
    from ..files import check_output_path
    from ..pipeline import Pipeline
    from ..sources import is_live_spec, open_source

    allowed_origins = check_origins(allowed_origins)
    config = load_config(config_path) if config_path else PipelineConfig()
    calibration = load_calibration(calibration_path) if calibration_path else None
    out = Path(calibration_out)
    try:
        check_output_path(out, what="the calibration")
    except OutputError:
        raise OutputError(
            f"--calibration-out {out}: not a file in an existing folder; give a file path"
        ) from None
    opened = [open_source(source_spec)]  # fail early, with the source's own message
    name = opened[0].name
    # sources that know their length (npz, PNG folder, simulator) can be played again as they are
    reuse = hasattr(opened[0], "__len__")

    def next_source() -> DepthSource:
        # the first pass uses the source opened above; later passes open it again
        return opened.pop() if opened else open_source(source_spec)

    try:
        pipeline = Pipeline(config, calibration=calibration, surface_frames=surface_frames)
        page = WebPage((host, port), pipeline, source_name=name, calibration_out=out,
                       allowed_origins=allowed_origins)
        page.__enter__()
    except BaseException:
        opened[0].close()
        raise
    runner = SourceLoop(next_source, pipeline, page,
                        realtime=realtime and not is_live_spec(source_spec), loop=loop,
                        reuse_source=reuse)
    try:
        runner.start()
        announce(f"depthtouch: serving {name} at {page.url} (Ctrl-C to stop)")
        while not runner.join(0.5):
            pass
        announce(f"depthtouch: {name} has finished ({runner.stats.frames} frames)")
    finally:
        runner.stop()
        runner.join(5.0, raise_error=False)
        page.__exit__()
        for source in opened:
            source.close()
    return runner.stats


def check_origins(values: Sequence[str]) -> list[str]:
    """``--allow-origin`` values as browsers send them (``scheme://host[:port]``); OutputError
    (one line) for anything else."""
    from urllib.parse import urlsplit

    out = []
    for v in values:
        u = urlsplit(v.strip())
        if u.scheme not in ("http", "https") or not u.hostname or u.path not in ("", "/"):
            raise OutputError(f"--allow-origin {v!r} is not an origin; give e.g. "
                              "http://localhost:5173 (scheme, host, optional port, no path)")
        out.append(v.strip().rstrip("/"))
    return out

