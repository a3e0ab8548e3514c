"""The live loop without a camera: stillness check and countdown (the learning gate), frame
dropping with a slow consumer (the camera stream), reconnect after a simulated disconnect, clean
stop; run_live end to end on a paced synthetic recording."""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Iterator

import numpy as np
import pytest

from depthtouch.checks import parse_address
from depthtouch.config import PipelineConfig
from depthtouch.driver import Pacer
from depthtouch.errors import ConfigError, SourceError
from depthtouch.live import LiveConfig, LiveLoop, LiveStatus, format_status, run_live
from depthtouch.sources import write_npz
from depthtouch.sources.base import SourceBase
from depthtouch.sources.camera import Delivery, Ended, LatestFrameMailbox
from depthtouch.sources.realsense import SourceDisconnected
from depthtouch.surface.gate import LearningGate, StillnessGate, motion_fraction
from depthtouch.types import Frame, FrameResult, TouchEvent, TouchPoints
from synth import K_640, Finger, make_recording

H, W = 24, 32
PLANE = 1000


def scene(n: int, blobs: dict[int, tuple[int, int]] | None = None, seed: int = 0,
          t0: float = 0.0, fps: float = 30.0) -> list[Frame]:
    """n frames of a noisy plane at 1000 mm; ``blobs[i] = (row, col)`` puts a 6x6 object 60 mm
    above the plane at frame i."""
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        d = PLANE + rng.normal(0, 1.5, (H, W))
        if blobs and i in blobs:
            r, c = blobs[i]
            d[r:r + 6, c:c + 6] -= 60
        out.append(Frame(np.rint(d).astype(np.uint16), t0 + i / fps, i, 0.001, None))
    return out


class FakePipeline:
    """Learns for ``learn_frames`` frames (those its learning gate lets through), then reports
    one touch while the centre is raised."""

    def __init__(self, learn_frames: int = 5, work_s: float = 0.0,
                 gate: LearningGate | None = None) -> None:
        self.learn_frames, self.work_s, self.gate = learn_frames, work_s, gate
        self.seen: list[Frame] = []
        self.learned_from: list[int] = []
        self.resets = 0
        self.next_id = 1
        self.active: int | None = None
        self.on_process = None

    @property
    def learning(self) -> bool:
        return len(self.learned_from) < self.learn_frames

    def _result(self, frame: Frame, events: list[TouchEvent], status: str) -> FrameResult:
        return FrameResult(frame, events, TouchPoints.empty(), status,  # type: ignore[arg-type]
                           {} if status == "learning" else {"total": 0.1},
                           min(1.0, len(self.learned_from) / self.learn_frames),
                           self.gate.note if self.gate is not None and self.learning else "")

    def process(self, frame: Frame) -> FrameResult:
        if self.on_process is not None:
            self.on_process(frame)
        if self.work_s:
            time.sleep(self.work_s)
        self.seen.append(frame)
        if self.learning:
            verdict = self.gate.update(frame) if self.gate is not None else "learn"
            if verdict == "restart":
                self.learned_from = []
                self.resets += 1
            elif verdict == "learn":
                self.learned_from.append(frame.index)
            return self._result(frame, [], "learning")
        touching = int(frame.depth[H // 2, W // 2]) < PLANE - 30
        t = frame.timestamp_s
        events: list[TouchEvent] = []
        if touching and self.active is None:
            self.active, self.next_id = self.next_id, self.next_id + 1
            events = [TouchEvent(frame.index, t, self.active, "down", 16.0, 12.0)]
        elif touching:
            events = [TouchEvent(frame.index, t, self.active or 0, "move", 16.0, 12.0)]
        elif self.active is not None:
            events = [TouchEvent(frame.index, t, self.active, "up", 16.0, 12.0)]
            self.active = None
        return self._result(frame, events, "ok")

    def finish(self) -> FrameResult | None:
        if self.learning and self.gate is not None:
            self.learned_from = []
            self.gate.reset()
        if self.active is None or not self.seen:
            return None
        last = self.seen[-1]
        ev = TouchEvent(last.index, last.timestamp_s, self.active, "up", 16.0, 12.0)
        self.active = None
        return self._result(last, [ev], "ended")


def live_loop(factory, pipe: FakePipeline, sinks, config: LiveConfig | None = None,
              **kw) -> LiveLoop:  # type: ignore[no-untyped-def]
    """A LiveLoop whose fake pipeline learns through the loop's learning gate."""
    config = config or LiveConfig()
    pipe.gate = LearningGate(config.gate())
    return LiveLoop(factory, pipe, sinks, config=config, gate=pipe.gate, **kw)


class ListSink:
    def __init__(self, after_send=None) -> None:  # type: ignore[no-untyped-def]
        self.frames: list[Frame] = []
        self.events: list[TouchEvent] = []
        self.flushes = 0
        self.after_send = after_send

    def send(self, result: FrameResult) -> None:
        self.frames.append(result.frame)
        self.events += result.events
        if self.after_send is not None:
            self.after_send()

    def flush(self) -> None:
        self.flushes += 1

    def close(self) -> None:
        pass


class StepSource(SourceBase):
    """Yields the next frame only once the loop has handled the previous one (no drops: the
    tests of the countdown are deterministic); raises ``fail`` after ``fail_after`` frames."""

    def __init__(self, frames: list[Frame], step: threading.Semaphore | None = None,
                 fail_after: int | None = None, fail: BaseException | None = None) -> None:
        self._frames, self.step = frames, step
        self.fail_after, self.fail = fail_after, fail
        self.closed = False
        self.resolution_wh = (W, H)

    def frames(self) -> Iterator[Frame]:
        for i, f in enumerate(self._frames):
            if self.fail_after is not None and i == self.fail_after:
                raise self.fail or SourceDisconnected("camera unplugged; check the cable")
            if self.step is not None:
                while not self.step.acquire(timeout=0.05):
                    if self.closed:
                        return
            yield f

    def close(self) -> None:
        self.closed = True


def stepped(frames: list[Frame], **kw):  # type: ignore[no-untyped-def]
    step = threading.Semaphore(1)
    sink = ListSink(after_send=step.release)
    return StepSource(frames, step, **kw), sink


# --- pure pieces ------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("change_mm", "rows", "zero_rows", "want"),
    [
        (0, 0, 0, 0.0),
        (20, H // 2, 0, 0.5),  # half the image 20 mm nearer
        (10, H // 2, 0, 0.0),  # below the 15 mm threshold
        (-40, H, 0, 1.0),
        (20, H // 2, H // 2, 0.0),  # the changed half is missing in the new frame: not motion
    ],
)
def test_motion_fraction(change_mm, rows, zero_rows, want):  # type: ignore[no-untyped-def]
    ref = np.full((H, W), 1000, np.uint16)
    cur = ref.copy()
    cur[:rows] = 1000 - change_mm
    cur[:zero_rows] = 0
    assert motion_fraction(ref, cur, 0.001, 15.0) == pytest.approx(want)
    assert np.all(ref == 1000)  # inputs untouched


def test_motion_fraction_edge_cases():
    z = np.zeros((H, W), np.uint16)
    assert motion_fraction(z, z, 0.001, 15.0) == 0.0
    assert motion_fraction(z, np.zeros((H + 2, W), np.uint16), 0.001, 15.0) == 1.0
    # units: 0.0001 m per unit, 20 mm = 200 units
    ref = np.full((H, W), 10000, np.uint16)
    assert motion_fraction(ref, ref - 200, 0.0001, 15.0) == 1.0
    assert motion_fraction(ref, ref - 100, 0.0001, 15.0) == 0.0


def test_stillness_gate_counts_frame_time_and_restarts_on_motion():
    frames = scene(12, blobs={5: (4, 4)})
    gate = StillnessGate(15.0, 0.01)
    still, moved = [], []
    for f in frames:
        still.append(gate.update(f))
        moved.append(gate.moved)
    assert still[0] == 0.0 and still[4] == pytest.approx(4 / 30)
    assert moved == [False] * 5 + [True, True] + [False] * 5
    assert still[6] == 0.0 and gate.last_motion_s == pytest.approx(6 / 30)  # the blob left
    assert still[11] == pytest.approx(5 / 30)


def test_mailbox_keeps_only_the_newest():
    mb = LatestFrameMailbox()
    assert mb.get(0.01) is None
    f = scene(3)
    for i, fr in enumerate(f):
        mb.put(Delivery(fr, i, float(i)))
    got = mb.get(0.01)
    assert isinstance(got, Delivery) and got.seq == 2 and mb.dropped == 2 and mb.put_count == 3
    mb.put(Delivery(f[0], 3, 3.0))
    mb.finish(None)
    got = mb.get(0.01)
    assert isinstance(got, Delivery) and got.seq == 3  # the unread frame comes before the end
    assert mb.get(0.01) == Ended(None)


@pytest.mark.parametrize(
    ("kw", "match"),
    [
        ({"countdown_s": -1.0}, r"live.countdown_s = -1.0 is out of range; allowed \[0.0, 60.0\]"),
        ({"motion_fraction": 0.0}, "live.motion_fraction"),
        ({"backoff_initial_s": 2.0, "backoff_max_s": 1.0}, "live.backoff_max_s"),
        ({"status_hz": 0.0}, "live.status_hz"),
        ({"learn_max_hz": 0.0}, "live.learn_max_hz"),
    ],
)
def test_live_config_errors(kw, match):  # type: ignore[no-untyped-def]
    with pytest.raises(ConfigError, match=match):
        LiveConfig(**kw)


@pytest.mark.parametrize(
    ("text", "want"),
    [("127.0.0.1:9000", ("127.0.0.1", 9000)), ("0.0.0.0", ("0.0.0.0", 8765)),
     (":0", ("127.0.0.1", 0)), ("8000", ("127.0.0.1", 8000)), ("[::1]:80", ("::1", 80)),
     ("host:port", None), ("h:70000", None)],
)
def test_parse_web_address(text, want):  # type: ignore[no-untyped-def]
    if want is None:
        with pytest.raises(ConfigError, match="not HOST:PORT"):
            parse_web_address(text)
    else:
        assert parse_web_address(text) == want


def parse_web_address(text: str) -> tuple[str, int]:
    return parse_address(text, what="web address", default_port=8765, default_host="127.0.0.1",
                         allow_port_zero=True)


def test_format_status_is_one_line():
    s = LiveStatus("running", "surface learned", 89.7, 4.25, 100, 3, 2, 1)
    line = format_status(s)
    assert "\n" not in line
    assert line.startswith("[running]") and " 89.7 fps" in line and "4.2 ms/frame" in line
    assert "dropped 3" in line and "touches 2" in line and "reconnects 1" in line


def test_pacer_waits_for_the_frame_times():
    now = [100.0]
    waits: list[float] = []

    def wait(s: float) -> bool:
        waits.append(s)
        now[0] += s
        return False

    pacer = Pacer(2.0, clock=lambda: now[0], wait=wait)
    got = [f.index for f in scene(4, t0=5.0, fps=10.0) if not pacer.until(f.timestamp_s)]
    assert got == [0, 1, 2, 3] and waits == pytest.approx([0.05, 0.05, 0.05])
    with pytest.raises(ConfigError, match="speed"):
        Pacer(0)


# --- the loop ---------------------------------------------------------------------------------
def test_countdown_then_learning_then_touches():
    frames = scene(40, blobs={i: (H // 2 - 3, W // 2 - 3) for i in range(25, 31)})
    src, sink = stepped(frames)
    pipe = FakePipeline(learn_frames=5)
    statuses: list[LiveStatus] = []
    ticks = iter(range(10**6))  # a clock that moves 1 s per reading: every frame reports
    loop = live_loop(lambda: src, pipe, [sink], config=LiveConfig(countdown_s=0.2),
                    status=statuses.append, clock=lambda: float(next(ticks)))
    res = loop.run()
    assert res.processed == 40 and res.dropped == 0 and res.received == 40
    # frame 6 (t = 0.2 s) ends the countdown; learning uses the next 5 frames
    assert pipe.learned_from == [7, 8, 9, 10, 11]
    assert [(e.frame, e.state) for e in sink.events] == [(25, "down")] + [
        (i, "move") for i in range(26, 31)] + [(31, "up")]
    phases = [s.phase for s in statuses]
    assert phases[0] == "waiting" and "learning" in phases and phases[-1] == "running"
    assert any("learning starts in" in s.message for s in statuses)
    left = [s.countdown_s for s in statuses if s.phase == "waiting"]
    assert left[0] == 0.2 and min(left) < 0.2 and left == sorted(left, reverse=True)
    assert len(sink.frames) == 40  # sinks see every processed frame, also while waiting
    assert src.closed and sink.flushes >= 1


def test_a_90_hz_camera_learns_from_30_frames_per_second():
    src, sink = stepped(scene(30, fps=90.0))
    pipe = FakePipeline(learn_frames=5)
    res = live_loop(lambda: src, pipe, [sink], config=LiveConfig(countdown_s=0)).run()
    assert pipe.learned_from == [0, 3, 6, 9, 12] and res.processed == 30
    assert [f.index for f in pipe.seen[13:]] == list(range(13, 30))  # then every frame


def test_motion_before_and_during_learning_restarts_it():
    blobs = {i: (2 + i, 2 + 2 * i) for i in range(8)}  # something moves over the surface
    blobs.update({i: (10, 20) for i in range(16, 18)})  # an object passes during learning
    frames = scene(45, blobs=blobs, seed=1)
    src, sink = stepped(frames)
    pipe = FakePipeline(learn_frames=8)
    statuses: list[LiveStatus] = []
    res = live_loop(lambda: src, pipe, [sink], config=LiveConfig(countdown_s=0.2),
                   status=statuses.append).run()
    assert any("clear the surface" in s.message for s in statuses)
    assert pipe.resets == 1 and res.learn_restarts == 1
    # still from frame 8 on: countdown to frame 14, learning 15.. until the object at 16;
    # then still from 18 (against the frame without it): countdown to 24, learning 25..32
    assert pipe.learned_from == list(range(25, 33))
    assert res.processed == 45


def test_disconnect_reopens_with_backoff_and_keeps_time_increasing():
    touch = {i: (H // 2 - 3, W // 2 - 3) for i in range(10, 30)}
    first = scene(30, blobs=touch, t0=1000.0)
    second = scene(12, t0=0.0, seed=2)  # the device clock restarted after the replug
    opened: list[StepSource] = []
    sink = ListSink(after_send=lambda: opened[-1].step.release())  # type: ignore[union-attr]
    attempts = [0]

    def factory() -> StepSource:
        attempts[0] += 1
        if attempts[0] == 1:
            src = StepSource(first, threading.Semaphore(1), fail_after=15)
        elif attempts[0] in (2, 3):
            raise SourceError("no RealSense camera found; connect one")
        else:
            src = StepSource(second, threading.Semaphore(1))
        opened.append(src)
        return src

    pipe = FakePipeline(learn_frames=1)
    pipe.learned_from = [0]  # a saved surface: no learning, no countdown
    statuses: list[LiveStatus] = []
    cfg = LiveConfig(backoff_initial_s=0.01, backoff_max_s=0.02)
    res = live_loop(factory, pipe, [sink], config=cfg, status=statuses.append).run()
    assert attempts[0] == 4 and res.reconnects == 1
    assert res.received == 27 and res.processed == 27 and all(s.closed for s in opened)
    assert any(s.phase == "reconnecting" for s in statuses)
    # the touch held at the disconnect ends there
    assert [(e.frame, e.state) for e in sink.events if e.state != "move"] == [
        (10, "down"), (14, "up")]
    # the ``up`` at the disconnect goes out with the last frame again
    assert sink.frames[15] is sink.frames[14]
    frames = sink.frames[:15] + sink.frames[16:]
    t = np.array([f.timestamp_s for f in frames])
    idx = [f.index for f in frames]
    assert t[0] == 0.0 and np.all(np.diff(t) > 0) and idx == list(range(27))
    np.testing.assert_allclose(np.diff(t[15:]), 1 / 30, atol=1e-9)


def test_no_camera_at_start_raises():
    def factory() -> SourceBase:
        raise SourceError("no RealSense camera found; connect one")

    with pytest.raises(SourceError, match="no RealSense camera"):
        live_loop(factory, FakePipeline(), []).run()


def test_a_bug_in_the_source_is_raised_not_retried():
    src = StepSource(scene(5), fail_after=2, fail=ZeroDivisionError("bug"))
    with pytest.raises(ZeroDivisionError):
        live_loop(lambda: src, FakePipeline(learn_frames=1), []).run()
    assert src.closed


class PacedSimSource(SourceBase):
    """A camera-like source: frames arrive in real time at ``fps``; counts what it produced."""

    def __init__(self, n: int, fps: float) -> None:
        self.n, self.fps = n, fps
        self.produced = 0
        self.resolution_wh = (W, H)
        self._frames = scene(n, blobs={i: (9, 13) for i in range(n // 2, n)}, fps=fps)

    def frames(self) -> Iterator[Frame]:
        start = time.monotonic()
        for i, f in enumerate(self._frames):
            wait = start + i / self.fps - time.monotonic()
            if wait > 0:
                time.sleep(wait)
            self.produced += 1
            yield f


def test_slow_consumer_drops_stale_frames_instead_of_queueing():
    src = PacedSimSource(60, fps=100.0)
    pipe = FakePipeline(learn_frames=2, work_s=0.03)  # 3 frame intervals per frame
    staleness: list[int] = []
    pipe.on_process = lambda f: staleness.append(src.produced - 1 - f.index)
    res = live_loop(lambda: src, pipe, [], config=LiveConfig(countdown_s=0.0)).run()
    assert res.received == 60 and res.dropped > 0
    assert res.processed + res.dropped == res.received
    indices = [f.index for f in pipe.seen]
    assert indices == sorted(set(indices))
    # each processed frame was the newest one (or one behind) when its processing started:
    # with a queue it would fall further behind with every frame
    assert max(staleness) <= 2
    assert res.latency_ms_max > 0.0


def test_stop_event_ends_the_run_and_lifts_touches():
    frames = scene(400, blobs={i: (H // 2 - 3, W // 2 - 3) for i in range(3, 400)})
    stop = threading.Event()
    step = threading.Semaphore(1)

    def after_send() -> None:
        step.release()
        if len(sink.frames) == 10:
            stop.set()

    sink = ListSink(after_send=after_send)
    src = StepSource(frames, step)
    pipe = FakePipeline(learn_frames=1)
    pipe.learned_from = [0]
    res = live_loop(lambda: src, pipe, [sink], config=LiveConfig(countdown_s=0)).run(
        stop_event=stop)
    assert res.processed == 10 and src.closed
    assert [e.state for e in sink.events][-1] == "up" and sink.flushes >= 1


def test_max_frames():
    src, sink = stepped(scene(50))
    res = live_loop(lambda: src, FakePipeline(learn_frames=1), [sink],
                   config=LiveConfig(countdown_s=0)).run(max_frames=7)
    assert res.processed == 7 and src.closed


# --- run_live end to end ----------------------------------------------------------------------
def _recording(tmp_path):  # type: ignore[no-untyped-def]
    script = [[Finger(100 + 3 * i, 120)] for i in range(15)] + [[]] * 4
    depth, ts = make_recording(24, script, shape=(240, 320), seed=5)
    K = K_640.copy()
    K[0, 2], K[1, 2] = 159.5, 119.5
    return write_npz(tmp_path / "rec.npz", depth, ts, 0.001, K)


def test_run_live_on_a_paced_recording_writes_events(tmp_path):  # type: ignore[no-untyped-def]
    rec = _recording(tmp_path)
    out = tmp_path / "events.jsonl"
    cfg = PipelineConfig().replace(surface={"learn_frames": 8})
    res = run_live(str(rec), config=cfg, events_path=out, show_status=False,
                   live_config=LiveConfig(countdown_s=0.2), save_surface_path=tmp_path / "s.npz")
    assert res.received == 43 and not res.interrupted
    lines = [json.loads(x) for x in out.read_text().splitlines()]
    states = [x["state"] for x in lines]
    assert states.count("down") == 1 and states[-1] == "up"
    assert all(x["frame"] >= 15 for x in lines)  # after countdown (7) + learning (8)
    assert (tmp_path / "s.npz").is_file()


def test_run_live_ctrl_c_commits_the_events_file(tmp_path):  # type: ignore[no-untyped-def]
    frames = scene(30)

    def factory() -> SourceBase:
        return StepSource(frames, fail_after=20, fail=KeyboardInterrupt())

    out = tmp_path / "ev.jsonl"
    res = run_live(factory, events_path=out, show_status=False,
                   live_config=LiveConfig(countdown_s=0))
    assert res.interrupted and out.is_file()
    assert not [p for p in tmp_path.iterdir() if p.name.endswith(".part")]


def test_run_live_rejects_a_surface_of_another_size(tmp_path):  # type: ignore[no-untyped-def]
    from depthtouch.errors import SurfaceError
    from depthtouch.surface.model import learn_surface

    surf = learn_surface(np.full((5, 10, 12), 1000, np.uint16), 0.001)
    path = surf.save(tmp_path / "s.npz")
    out = tmp_path / "ev.jsonl"
    with pytest.raises(SurfaceError, match="surface file is 12x10 but list gives 32x24"):
        run_live(lambda: _named(StepSource(scene(5))), surface_path=path, events_path=out,
                 show_status=False)
    assert not out.exists()  # an error run keeps no events file


def _named(src: StepSource) -> StepSource:
    src.name = "list"
    return src


def test_run_live_with_the_web_page(tmp_path):  # type: ignore[no-untyped-def]
    pytest.importorskip("aiohttp")
    res = run_live(lambda: PacedList(scene(20)), serve="127.0.0.1:0",
                   show_status=False, live_config=LiveConfig(countdown_s=0))
    assert res.received == 20 and res.processed + res.dropped == 20 and res.processed > 10


class PacedList(StepSource):
    """Frames at their own pace (30 fps), as a camera delivers them."""

    def frames(self) -> Iterator[Frame]:
        pacer = Pacer(1.0)
        for f in super().frames():
            pacer.until(f.timestamp_s)
            yield f
