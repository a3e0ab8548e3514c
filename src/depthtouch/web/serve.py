"""``depthtouch serve``: a depth source, the pipeline and the web page, wired together.

:class:`SourceLoop` reads a source in a background thread, paces recordings and the simulator at
their own timestamps (so a person can watch), runs the pipeline on each frame and hands the
events and a few height maps per second to a :class:`~depthtouch.web.server.WebServer`. A
finished recording starts again (the surface is learned again, the page is told to clear its
trails) or, with ``loop=False``, ends with a message on the page.
"""

from __future__ import annotations

import signal
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..errors import DepthTouchError, OutputError
from ..sources.base import DepthSource
from .server import WebServer


@dataclass
class LoopStats:
    """Counters of a serve run: frames processed, events sent, passes over the source."""

    frames: int = 0
    events: int = 0
    passes: int = 0


class SourceLoop:
    """Source -> pipeline -> web server, in a background thread.

    open_source: returns a fresh source (called again for each pass when looping).
    pipeline: an object with ``process(frame) -> list[TouchEvent]``, ``height_map_mm(frame)``,
        ``reset()`` and (optional) ``last_timing_ms`` / ``learning`` for the status line.
    realtime: sleep until each frame's timestamp (relative to the first frame) before processing
        it (default True); False processes as fast as possible.
    loop: start a finished recording again (default True); False stops after one pass.
    max_passes: stop after this many passes even when looping (None = never).
    reuse_source: open the source once and iterate its ``frames()`` again for each pass
        (default False: open a fresh source per pass). Right for recordings held in memory and
        for the simulator, which renders its scene when opened.

    A DepthTouchError from the source or the pipeline stops the loop and is kept in ``error``
    (re-raised by :meth:`join`); :meth:`stop` ends it at the next frame.
    """

    def __init__(
        self,
        open_source: Callable[[], DepthSource],
        pipeline: Any,
        server: WebServer,
        *,
        realtime: bool = True,
        loop: bool = True,
        max_passes: int | None = None,
        reuse_source: bool = False,
    ) -> None:
        self.open_source = open_source
        self.pipeline = pipeline
        self.server = server
        self.realtime = realtime
        self.loop = loop
        self.max_passes = max_passes
        self.reuse_source = reuse_source
        self.stats = LoopStats()
        self.error: BaseException | None = None
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        server.attach_pipeline(pipeline)

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
        source: DepthSource | None = None
        try:
            while not self._stop.is_set():
                if source is None:
                    source = self.open_source()
                self._one_pass(source)
                self.stats.passes += 1
                if not self.reuse_source:
                    source.close()
                    source = None
                if self._stop.is_set():
                    break
                done = not self.loop or (
                    self.max_passes is not None and self.stats.passes >= self.max_passes
                )
                if done:
                    self.server.notify({"type": "info", "message": "the recording has finished"})
                    break
                self.pipeline.reset()
                self.server.sink.reset()
                self.server.notify({"type": "reset", "message": "the recording starts again"})
        except DepthTouchError as e:
            self.error = e
            self.server.notify({"type": "info", "message": f"stopped: {e}"})
        except BaseException as e:  # a bug: keep it for join() to re-raise with its traceback
            self.error = e
        finally:
            if source is not None:
                source.close()

    def _one_pass(self, source: DepthSource) -> None:
        t_first: float | None = None
        wall_first = 0.0
        sink = self.server.sink
        last_frame = None
        for frame in source.frames():
            if self._stop.is_set():
                return
            last_frame = frame
            if self.realtime:
                if t_first is None:
                    t_first, wall_first = frame.timestamp_s, time.monotonic()
                delay = wall_first + (frame.timestamp_s - t_first) - time.monotonic()
                if delay > 0 and self._stop.wait(delay):
                    return
            events = self.pipeline.process(frame)
            sink.send(frame, events)
            self.stats.frames += 1
            self.stats.events += len(events)
            if self.server.height_due(frame.timestamp_s):
                self.server.publish_height(frame, self.pipeline.height_map_mm(frame))
        if last_frame is None:
            raise OutputError(f"{getattr(source, 'name', 'the source')} gave no frames; "
                              "check the recording")
        finish = getattr(self.pipeline, "finish", None)
        if callable(finish) and not self._stop.is_set():
            ended = list(finish())  # the touches still down get their "up"
            if ended:
                sink.send(last_frame, ended)


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
    announce: Callable[[str], None] = print,
    allowed_origins: Sequence[str] = (),
) -> LoopStats:
    """Serve the page for a source until Ctrl-C, or until a recording ends with ``loop=False``.

    Live cameras (``realsense``, ``openni``) are never paced: they deliver frames in real time.
    Errors (bad source, port taken, bad calibration file) raise DepthTouchError subclasses.
    allowed_origins: browser origins besides the page's own allowed on the WebSocket
    (``serve --allow-origin``), e.g. ``http://localhost:5173``.
    """
    from ..config import PipelineConfig, load_config
    from ..pipeline import Pipeline
    from ..sources import open_source

    allowed_origins = check_origins(allowed_origins)
    config = load_config(config_path) if config_path else PipelineConfig()
    calibration = None
    if calibration_path:
        from ..calibration import load_calibration

        calibration = load_calibration(calibration_path)
    out = Path(calibration_out)
    if out.is_dir() or not (out.parent if str(out.parent) else Path(".")).is_dir():
        raise OutputError(
            f"--calibration-out {out}: not a file in an existing folder; give a file path"
        )
    live = source_spec.split(":")[0] in _LIVE_SOURCES
    opened = [open_source(source_spec)]  # fail early, with the source's own message
    name = opened[0].name
    # sources that know their length (npz, PNG folder, simulator) can be played again as they are
    reuse = hasattr(opened[0], "__len__")

    def next_source() -> DepthSource:
        # the first pass uses the source opened above; later passes open it again
        return opened.pop() if opened else open_source(source_spec)

    try:
        pipeline = Pipeline(config, surface_frames=surface_frames)
        server = WebServer(host, port, calibration=calibration, calibration_out=out,
                           source_name=name, allowed_origins=allowed_origins)
        server.start()
    except BaseException:
        opened[0].close()
        raise
    runner = SourceLoop(next_source, pipeline, server, realtime=realtime and not live,
                        loop=loop, reuse_source=reuse)
    old_term = _stop_on_sigterm()
    try:
        runner.start()
        announce(f"depthtouch: serving {name} at {server.url} (Ctrl-C to stop)")
        while not runner.join(0.5):
            pass
        announce(f"depthtouch: {name} has finished ({runner.stats.frames} frames)")
    finally:
        runner.stop()
        runner.join(5.0, raise_error=False)
        server.stop()
        for source in opened:
            source.close()
        if old_term is not None:
            signal.signal(signal.SIGTERM, old_term)
    return runner.stats


_LIVE_SOURCES = ("realsense", "openni")


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


def _interrupt(signum: int, frame: Any) -> None:
    raise KeyboardInterrupt


def _stop_on_sigterm() -> Any:
    """Make SIGTERM (a service manager stopping us) end the serve loop like Ctrl-C."""
    if threading.current_thread() is not threading.main_thread():
        return None
    return signal.signal(signal.SIGTERM, _interrupt)
