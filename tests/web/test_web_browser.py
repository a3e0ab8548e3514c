"""The web page in a real browser (Playwright driving Debian's /usr/bin/chromium).

The page connects, shows the touches of a replayed recording, draws a stroke for a drag, zooms on
a pinch and completes the calibration flow with injected touches. Skipped, with the reason, when
chromium or Playwright is missing.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from depthtouch.calibration import apply_calibration, default_targets, load_calibration
from depthtouch.pipeline import Pipeline
from depthtouch.sources import open_source, write_npz
from depthtouch.types import TouchEvent
from depthtouch.web.serve import SourceLoop, page_sinks
from depthtouch.web.server import WebServer

CHROMIUM = Path("/usr/bin/chromium")
ARGS = [
    "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
    "--disable-background-networking", "--disable-component-update", "--disable-sync",
]
RES = (160, 120)
PAD_BG = [250, 250, 250, 255]

pytestmark = pytest.mark.browser

if not CHROMIUM.exists():
    pytest.skip(
        "browser tests need /usr/bin/chromium (apt-get install -y chromium)",
        allow_module_level=True,
    )
sync_api = pytest.importorskip("playwright.sync_api", reason="browser tests need playwright")


@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    with sync_api.sync_playwright() as p:
        b = p.chromium.launch(executable_path=str(CHROMIUM), args=ARGS)
        try:
            yield b
        finally:
            b.close()


@pytest.fixture
def server(tmp_path: Path) -> Iterator[WebServer]:
    # a long queue: the tests inject bursts faster than 30 fps (skipping is tested elsewhere)
    s = WebServer("127.0.0.1", 0, calibration_out=tmp_path / "cal.json", queue_size=256)
    s.start()
    try:
        yield s
    finally:
        s.stop()


@pytest.fixture
def page(browser: Any, server: WebServer) -> Iterator[Any]:
    # bypass_csp lets Playwright evaluate test expressions; test_page_obeys_its_csp checks
    # the page itself without it
    pg = browser.new_page(viewport={"width": 1500, "height": 800}, bypass_csp=True)
    errors: list[str] = []
    pg.on("pageerror", lambda e: errors.append(str(e)))
    pg.goto(server.url)
    pg.wait_for_function(
        "document.getElementById('conn').textContent === 'connected'"
        " && window.depthtouch.targets !== null",
        timeout=10_000,
    )
    try:
        yield pg
    finally:
        pg.close()
    assert errors == []


class Feed:
    """Injects touch frames with increasing frame numbers and times (30 fps)."""

    def __init__(self, server: WebServer) -> None:
        self.server = server
        self.i = 0

    def frame(self, touches: list[tuple[int, str, float, float]], **extra: float) -> None:
        t = self.i / 30.0
        evs = [TouchEvent(self.i, t, tid, st, x, y, dict(extra))  # type: ignore[arg-type]
               for tid, st, x, y in touches]
        evs = apply_calibration(evs, self.server.calibration)  # as the pipeline does
        self.server.inject(evs, frame_index=self.i, t_s=t)
        self.i += 1

    def wait(self, page: Any) -> None:
        page.wait_for_function(f"window.depthtouch.lastFrame >= {self.i - 1}", timeout=10_000)


def depth_to_pad(x: float, y: float, pad_wh: tuple[int, int] = (960, 540)) -> tuple[int, int]:
    w, h = RES
    s = min(pad_wh[0] / w, pad_wh[1] / h)
    return round((pad_wh[0] - w * s) / 2 + x * s), round((pad_wh[1] - h * s) / 2 + y * s)


def pad_pixel(page: Any, x: int, y: int) -> list[int]:
    return page.evaluate(
        "([x, y]) => Array.from(document.getElementById('pad').getContext('2d')"
        ".getImageData(x, y, 1, 1).data)",
        [x, y],
    )


def test_page_obeys_its_csp(browser: Any, server: WebServer) -> None:
    pg = browser.new_page()
    problems: list[str] = []
    pg.on("pageerror", lambda e: problems.append(str(e)))
    pg.on("console", lambda m: problems.append(m.text) if m.type == "error" else None)
    try:
        pg.goto(server.url)
        pg.locator("#conn", has_text="connected").wait_for(timeout=10_000)
        Feed(server).frame([(1, "down", 10.0, 10.0)])
        pg.locator("#touch-list li").first.wait_for(timeout=10_000)
        assert pg.text_content("#seen") == "1"
    finally:
        pg.close()
    assert problems == []


# --- a replayed recording -------------------------------------------------------------------------
def finger_recording(path: Path, n: int = 80, learn: int = 15, fps: float = 60.0) -> Path:
    """Plane at 800 mm; a finger (tip touching, hand above) moves from (40, 40) to (120, 80)."""
    w, h = RES
    rng = np.random.default_rng(7)
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    depth = np.empty((n, h, w), np.uint16)
    for i in range(n):
        height = np.zeros((h, w), np.float32)
        if i >= learn:
            s = min(1.0, (i - learn) / (n - learn - 10))
            tx, ty = 40 + 80 * s, 40 + 40 * s
            along = yy - ty
            finger = (along >= 0) & (along < 25) & (np.abs(xx - tx) < 3.0)
            height[finger] = 10.0 + 1.2 * along[finger]
            height[(xx - tx) ** 2 / 196 + (yy - ty - 35) ** 2 / 144 < 1] = 60.0
        noisy = 800.0 - height + rng.normal(0, 1.0, (h, w))
        depth[i] = np.round(noisy).astype(np.uint16)
    K = np.array([[145.0, 0, w / 2], [0, 145.0, h / 2], [0, 0, 1]])
    return write_npz(path, depth, np.arange(n) / fps, 0.001, K)


def test_page_shows_touches_of_a_replay(
    page: Any, server: WebServer, tmp_path: Path
) -> None:
    rec = finger_recording(tmp_path / "finger.npz")
    web = SimpleNamespace(server=server, sinks=page_sinks(server))
    runner = SourceLoop(lambda: open_source(rec), Pipeline(surface_frames=12), web,
                        realtime=True, loop=False).start()
    try:
        assert runner.join(20.0)
        page.wait_for_function("window.depthtouch.seen.size >= 1", timeout=10_000)
        page.wait_for_function("window.depthtouch.heightImage !== null", timeout=10_000)
    finally:
        runner.stop()
    assert runner.stats.events > 20
    assert int(page.text_content("#seen")) == len(page.evaluate(
        "[...window.depthtouch.seen]"))
    trail = page.evaluate("[...window.depthtouch.trails.values()].map(t => t.pts)")
    pts = np.array([p for tr in trail for p in tr])
    assert len(pts) > 10
    # the touch followed the finger from (40, 40) to (120, 80)
    assert pts[:, 0].min() < 60 and pts[:, 0].max() > 100
    assert np.all(np.abs(pts[:, 1] - (40 + (pts[:, 0] - 40) / 2)) < 6)
    status = page.text_content("#status")
    assert "fps" in status and "ms/frame" in status and "– ms/frame" not in status
    assert page.evaluate("window.depthtouch.res") == list(RES)
    # the live view shows the colour height map (not the empty grey)
    px = page.evaluate(
        "Array.from(document.getElementById('live').getContext('2d')"
        ".getImageData(5, 5, 1, 1).data)"
    )
    assert px[:3] != [34, 34, 34]
    # the drag drew a stroke on the pad where the touches were
    for x, y in pts[5:-5:max(1, len(pts) // 8)]:
        assert pad_pixel(page, *depth_to_pad(x, y)) != PAD_BG, (x, y)
    assert pad_pixel(page, *depth_to_pad(40, 100)) == PAD_BG
    page.screenshot(path=str(tmp_path / "web.png"))


@pytest.mark.slow
def test_page_with_the_simulator(page: Any, server: WebServer) -> None:
    """`depthtouch serve --source sim:drags` end to end (the scene takes seconds to render)."""
    runner = SourceLoop(lambda: open_source("sim:drags"), Pipeline(), server,
                        realtime=False, loop=False).start()
    try:
        assert runner.join(120.0)
    finally:
        runner.stop()
    page.wait_for_function("window.depthtouch.seen.size >= 2", timeout=20_000)
    drawn = page.evaluate(
        "(() => { const d = document.getElementById('pad').getContext('2d')"
        ".getImageData(0, 0, 960, 540).data; let n = 0;"
        " for (let i = 0; i < d.length; i += 4) if (d[i] < 240) n++; return n; })()"
    )
    assert drawn > 500


# --- drawing pad --------------------------------------------------------------------------------
def test_drag_draws_a_stroke(page: Any, server: WebServer) -> None:
    server.set_resolution(RES)
    feed = Feed(server)
    path = [(40 + 80 * k / 20, 40 + 40 * k / 20) for k in range(21)]
    for k, (x, y) in enumerate(path):
        feed.frame([(1, "down" if k == 0 else "move", x, y)])
    feed.frame([(1, "up", *path[-1])])
    feed.wait(page)
    for x, y in path[::4]:
        assert pad_pixel(page, *depth_to_pad(x, y)) != PAD_BG, (x, y)
    for x, y in [(40, 80), (120, 40), (10, 110), (150, 10)]:  # away from the stroke
        assert pad_pixel(page, *depth_to_pad(x, y)) == PAD_BG, (x, y)
    assert page.evaluate("window.depthtouch.touches.size") == 0
    page.click("#clear")
    assert pad_pixel(page, *depth_to_pad(80, 60)) == PAD_BG


def test_skipped_up_still_ends_the_touch(page: Any, server: WebServer) -> None:
    feed = Feed(server)
    feed.frame([(4, "down", 50.0, 50.0)])
    feed.frame([(4, "move", 52.0, 50.0)])
    feed.frame([])  # one frame without the touch (a bad frame): it is still down
    feed.wait(page)
    assert page.evaluate("window.depthtouch.touches.size") == 1
    feed.frame([(4, "move", 54.0, 50.0)])
    feed.frame([])
    feed.frame([])
    feed.wait(page)
    assert page.evaluate("window.depthtouch.touches.size") == 1
    feed.frame([])  # the third frame in a row without it: its "up" never reached this page
    feed.wait(page)
    assert page.evaluate("window.depthtouch.touches.size") == 0
    assert page.text_content("#touch-list") == ""


# --- pinch zoom ---------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "gestures, zoom",
    [
        ([(20.0, 60.0)], 3.0),  # pinch out: distance x3
        ([(60.0, 30.0)], 0.5),  # pinch in: distance /2
        ([(20.0, 60.0), (60.0, 30.0)], 1.5),  # out, lift, then in: scales compose
    ],
)
def test_pinch_changes_the_zoom(
    page: Any, server: WebServer, gestures: list[tuple[float, float]], zoom: float
) -> None:
    feed = Feed(server)
    ids = iter(range(10, 100))
    for d0, d1 in gestures:
        a, b = next(ids), next(ids)
        for k in range(11):
            d = d0 + (d1 - d0) * k / 10
            st = "down" if k == 0 else "move"
            feed.frame([(a, st, 80 - d / 2, 60.0), (b, st, 80 + d / 2, 60.0)])
        feed.frame([(a, "up", 80 - d1 / 2, 60.0), (b, "up", 80 + d1 / 2, 60.0)])
    feed.wait(page)
    got = float(page.get_attribute("#zoom", "data-zoom"))
    assert got == pytest.approx(zoom, rel=1e-3)
    assert f"{zoom:.2f}" in page.text_content("#zoom")
    page.click("#zoom-reset")
    assert page.get_attribute("#zoom", "data-zoom") == "1.000"


def test_pinch_from_touching_fingers_is_ignored(page: Any, server: WebServer) -> None:
    feed = Feed(server)
    for k in range(6):  # two touches 4 px apart: the ratio would be meaningless
        st = "down" if k == 0 else "move"
        feed.frame([(1, st, 78.0, 60.0), (2, st, 82.0 + 10 * k, 60.0)])
    feed.wait(page)
    assert page.get_attribute("#zoom", "data-zoom") == "1"


# --- calibration flow ---------------------------------------------------------------------------
def screen_to_depth(sx: float, sy: float) -> tuple[float, float]:
    """The test's 'true' camera: screen = (6 x + 30, 4.5 y + 10) in pad pixels."""
    return (sx - 30.0) / 6.0, (sy - 10.0) / 4.5


def tap(feed: Feed, tid: int, x: float, y: float, wobble: float = 0.4, n: int = 5) -> None:
    rng = np.random.default_rng(tid)
    for k in range(n):
        jx, jy = rng.uniform(-wobble, wobble, 2)
        feed.frame([(tid, "down" if k == 0 else "move", x + jx, y + jy)])
    feed.frame([(tid, "up", x, y)])


def test_calibration_flow_completes(page: Any, server: WebServer) -> None:
    server.set_resolution(RES)
    feed = Feed(server)
    targets = default_targets((960, 540), n=4)
    page.click("#calibrate")
    assert "target 1 of 4" in page.text_content("#cal-status")
    # a touch that slides is refused and the same target is asked again
    tap(feed, 1, *screen_to_depth(*targets[0]), wobble=0.0, n=1)
    feed.frame([(2, "down", 20.0, 20.0)])
    feed.frame([(2, "move", 40.0, 20.0)])
    feed.frame([(2, "up", 60.0, 20.0)])
    feed.wait(page)
    assert "moved" in page.text_content("#cal-status")
    for k, (sx, sy) in enumerate(targets[1:]):
        tap(feed, 3 + k, *screen_to_depth(sx, sy))
    page.wait_for_function(
        "document.getElementById('cal-status').dataset.done !== undefined", timeout=10_000
    )
    status = page.text_content("#cal-status")
    assert page.get_attribute("#cal-status", "data-done") == "ok", status
    err = float(status.split("reprojection error ")[1].split(" px")[0])
    assert err < 0.5
    cal = load_calibration(server.calibration_out)
    probe = np.array([[50.0, 40.0], [100.0, 90.0]])
    want = np.column_stack([6 * probe[:, 0] + 30, 4.5 * probe[:, 1] + 10])
    np.testing.assert_allclose(cal.to_screen(probe), want, atol=2.0)  # wobble averaged
    # the page now draws with the calibrated screen coordinates (sx, sy)
    page.wait_for_function("window.depthtouch.cal.loaded === true", timeout=10_000)
    assert "calibrated" in page.text_content("#pad-mode")
    x0, y0 = screen_to_depth(200.0, 300.0)
    for k in range(6):
        feed.frame([(20, "down" if k == 0 else "move", x0 + 10 * k, y0)])
    feed.frame([(20, "up", x0 + 50, y0)])
    feed.wait(page)
    for sx in (200, 260, 320, 440, 500):
        assert pad_pixel(page, sx, 300) != PAD_BG, sx
    assert pad_pixel(page, 350, 200) == PAD_BG
    assert math.isfinite(err)


# --- several cameras ------------------------------------------------------------------------------
def camera_cal(offset_px: float) -> Any:
    """Camera pixels -> the shared 960 x 540 screen: x + offset, then 6 x 4.5 (pad pixels)."""
    from depthtouch.calibration import Calibration

    H = np.diag([6.0, 4.5, 1.0]) @ np.array([[1.0, 0, offset_px], [0, 1.0, 0], [0, 0, 1.0]])
    return Calibration(H, (960, 540), 0.0)


def overlay_pixel(page: Any, x: int, y: int) -> list[int]:
    return page.evaluate(
        "([x, y]) => Array.from(document.getElementById('pad-overlay').getContext('2d')"
        ".getImageData(x, y, 1, 1).data)",
        [x, y],
    )


def test_two_cameras_parts_overlap_and_calibration_per_camera(
    browser: Any, tmp_path: Path
) -> None:
    """A fused replay of two cameras (one recording cut into columns [0, 100) and [60, 160)):
    the page draws each camera's part and their overlap on the pad, the finger crossing the
    seam is one touch, and camera 1 is calibrated alone with its targets in its own part."""
    from depthtouch.multicam import CameraFrame, MultiPipeline, merge_by_time
    from depthtouch.sources.base import ArraySource
    from depthtouch.web.serve import WebPage

    rec = open_source(finger_recording(tmp_path / "finger.npz"))
    depth = np.stack([f.depth for f in rec.frames()])  # type: ignore[union-attr]
    ts = np.asarray(rec.timestamps, np.float64)  # type: ignore[attr-defined]
    K, k_right = rec.K, rec.K.copy()  # type: ignore[attr-defined]
    k_right[0, 2] -= 60
    rec.close()
    views = [ArraySource(np.ascontiguousarray(depth[:, :, :100]), ts, 0.001, K),
             ArraySource(np.ascontiguousarray(depth[:, :, 60:]), ts, 0.001, k_right)]
    cals = [camera_cal(0.0), camera_cal(60.0)]
    multi = MultiPipeline([Pipeline(calibration=c, surface_frames=12) for c in cals])
    pg = browser.new_page(viewport={"width": 1500, "height": 800}, bypass_csp=True)
    errors: list[str] = []
    pg.on("pageerror", lambda e: errors.append(str(e)))
    with WebPage(("127.0.0.1", 0), multi, camera_names=["left.npz", "right.npz"],
                 calibration_out=tmp_path / "calibration.json", queue_size=256) as web:
        pg.goto(web.url)
        pg.wait_for_function("window.depthtouch.cameras !== null", timeout=10_000)
        merged = merge_by_time(views)
        runner = SourceLoop(lambda: merged, multi, web, realtime=True, loop=False,
                            reuse_source=True).start()
        assert runner.join(30.0)
        pg.wait_for_function("window.depthtouch.cameras.overlaps.length === 1", timeout=10_000)
        assert pg.text_content("#cams") == "2 cameras, 2 parts shown, 1 overlap"
        # one finger crossing the seam: one fused touch
        assert pg.evaluate("[...window.depthtouch.seen]") == [1]
        parts = pg.evaluate("window.depthtouch.cameras.cameras.map(c => c.footprint)")
        assert parts[0][1][0] == pytest.approx(594.0) and parts[1][0][0] == pytest.approx(360.0)
        # drawn on the pad: each part tinted, the overlap (x in [360, 594]) more
        left, both, right = (overlay_pixel(pg, x, 300) for x in (150, 480, 800))
        assert left[3] > 0 and right[3] > 0 and both[3] > max(left[3], right[3])
        assert overlay_pixel(pg, 957, 300)[3] == 0  # outside both parts
        pg.screenshot(path=str(tmp_path / "cameras.png"))
        # calibrate camera 1 alone: its targets lie in its own part (x > 594 on the pad)
        assert not pg.is_hidden("#cal-cam")
        pg.select_option("#cal-cam", "1")
        pg.click("#calibrate")
        assert "camera 1: touch target 1 of 4" in pg.text_content("#cal-status")
        targets = pg.evaluate("window.depthtouch.calib.targets")
        assert all(594.0 < x < 954.0 for x, _ in targets)
        feed = Feed(web.server)
        feed.i = 1000  # after the replay's frames
        truth = camera_cal(50.0)  # camera 1 has moved by 10 px: its new map
        for k, (sx, sy) in enumerate(targets):
            x, y = (sx / 6.0 - 50.0, sy / 4.5)
            feed.frame([(90 + k, "down", 30.0, 30.0)], cam=0)  # camera 0's touch: not paired
            for n in range(5):  # camera 1's touch on the target, held still
                feed.frame([(100 + k, "down" if n == 0 else "move", x, y)], cam=1)
            feed.frame([(100 + k, "up", x, y)], cam=1)
            feed.frame([(90 + k, "up", 30.0, 30.0)], cam=0)
        pg.wait_for_function("document.getElementById('cal-status').dataset.done !== undefined",
                             timeout=10_000)
        status = pg.text_content("#cal-status")
        assert pg.get_attribute("#cal-status", "data-done") == "ok", status
        assert status.startswith("camera 1 calibrated") and "calibration.cam1.json" in status
    pg.close()
    assert errors == []
    saved = load_calibration(tmp_path / "calibration.cam1.json")
    probe = np.array([[10.0, 20.0], [90.0, 100.0]])
    np.testing.assert_allclose(saved.to_screen(probe), truth.to_screen(probe), atol=0.05)
    assert not (tmp_path / "calibration.json").exists()
    # the loop maps camera 1 with it from its next frame on; camera 0 keeps its own
    multi.process(CameraFrame.of(next(iter(views[1].frames())), 1))  # type: ignore[arg-type]
    np.testing.assert_allclose(multi.calibrations[1].to_screen(probe), truth.to_screen(probe),
                               atol=0.05)
    assert multi.calibrations[0] is cals[0]
