"""Several cameras on the web page: each camera's part of the screen (footprint), the overlaps,
targets per camera that the fusion reports in that camera's pixels, the ``cameras`` message
(validated against the protocol schema), and the per-camera calibration endpoint wired to a
MultiPipeline."""

from __future__ import annotations

import asyncio
import http.client
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from aiohttp import ClientSession, WSMsgType

from depthtouch.calibration import Calibration
from depthtouch.fusion import Fusion, inside_px
from depthtouch.multicam import CameraFrame, MultiPipeline
from depthtouch.pipeline import Pipeline
from depthtouch.types import Frame, TouchEvent
from depthtouch.web.calibrate import camera_calibration_path
from depthtouch.web.cameras import CameraView, camera_targets, cameras_message, footprint, overlap
from depthtouch.web.serve import WebPage

jsonschema = pytest.importorskip("jsonschema")
SCHEMA = json.loads((Path(__file__).parents[2] / "src/depthtouch/web/protocol.schema.json")
                    .read_text())
SCREEN = (640, 480)


def check(message: dict[str, Any]) -> None:
    jsonschema.Draft202012Validator(SCHEMA).validate(message)
    sub = {**SCHEMA["$defs"][message["type"]], "$defs": SCHEMA["$defs"]}
    jsonschema.Draft202012Validator(sub).validate(message)


def shift(dx: float, rot180: bool = False) -> Calibration:
    """Camera pixels -> screen: a shift along x (and a half turn about the image centre)."""
    H = np.array([[1.0, 0.0, dx], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    if rot180:  # (x, y) -> (639 - x, 479 - y), then the shift
        H = H @ np.array([[-1.0, 0.0, 639.0], [0.0, -1.0, 479.0], [0.0, 0.0, 1.0]])
    return Calibration(H, SCREEN, 0.0)


# left camera covers screen x in [-232, 407], right one [232, 871] (the multi-view poses)
CALS = [shift(-232.0), shift(232.0, rot180=True)]


def views(res: tuple[int, int] | None = (640, 480)) -> list[CameraView]:
    return [CameraView(k, f"view{k}.npz", res, c) for k, c in enumerate(CALS)]


def test_footprints_overlap_and_targets_in_each_cameras_own_part() -> None:
    polys = [footprint(v) for v in views()]
    assert polys[0] is not None and polys[1] is not None
    assert polys[0][:, 0].min() == pytest.approx(-232.0)
    assert polys[1][:, 0].max() == pytest.approx(232.0 + 639.0)  # turned: corners swap
    inter = overlap(polys[0], polys[1])
    assert inter is not None
    assert (inter[:, 0].min(), inter[:, 0].max()) == pytest.approx((232.0, 407.0))
    assert overlap(polys[0], polys[0] + [2000.0, 0.0]) is None
    for k in range(2):
        t = camera_targets(k, polys, SCREEN)
        assert t.shape == (4, 2)
        assert all(inside_px(polys[k], p) >= 40.0 for p in t)  # deep in its own part
        assert all(inside_px(polys[1 - k], p) < 0.0 for p in t)  # outside the other's
        assert t[:, 0].min() >= 0 and t[:, 0].max() <= 639 and np.ptp(t[:, 1]) > 200
    # without a footprint (no frame or no calibration yet): the whole screen
    whole = camera_targets(0, [None, polys[1]], SCREEN)
    assert np.ptp(whole[:, 0]) > 400


def test_at_its_targets_the_fused_touch_is_in_that_cameras_pixels() -> None:
    """Both cameras see a finger at each target; the fused event's cam (whose x, y the page
    pairs with the target) is the camera being calibrated."""
    polys = [footprint(v) for v in views()]
    for k in range(2):
        for target in camera_targets(k, polys, SCREEN):
            f = Fusion()
            for cam, poly in enumerate(polys):
                f.set_view(cam, poly)
            out: list[TouchEvent] = []
            for cam in range(2):  # the other camera may see it too (near its edge)
                if inside_px(polys[cam], target) > -5.0:
                    extra = {"sx": float(target[0]), "sy": float(target[1])}
                    out = f.update(cam, 0.0, 0, [TouchEvent(0, 0.0, 1, "down", 1.0, 1.0, extra)])
            assert [e.extra["cam"] for e in out] == [k]


def test_cameras_message_validates_before_and_after_frames() -> None:
    before = cameras_message(views(None), SCREEN)
    check(before)
    assert [c["footprint"] for c in before["cameras"]] == [None, None]
    assert before["overlaps"] == []
    after = cameras_message(views(), SCREEN)
    check(after)
    assert [o["cams"] for o in after["overlaps"]] == [[0, 1]]
    assert all(c["calibrated"] and c["resolution_wh"] == [640, 480] for c in after["cameras"])


def test_calibration_paths_per_camera() -> None:
    out = Path("/x/calibration.json")
    assert camera_calibration_path(out, None) == out
    assert camera_calibration_path(out, 1) == Path("/x/calibration.cam1.json")


def frame(cam: int, i: int) -> CameraFrame:
    depth = np.full((480, 640), 1000, np.uint16)
    return CameraFrame.of(Frame(depth, i / 30.0, i), cam)


def post(port: int, body: dict[str, Any]) -> tuple[int, dict[str, Any]]:
    conn = http.client.HTTPConnection("127.0.0.1", port, timeout=10)
    try:
        conn.request("POST", "/api/calibration", body=json.dumps(body).encode(),
                     headers={"Content-Type": "application/json"})
        r = conn.getresponse()
        return r.status, json.loads(r.read())
    finally:
        conn.close()


async def first_messages(port: int, n: int) -> list[dict[str, Any]]:
    out: list[dict[str, Any]] = []
    async with ClientSession() as s, s.ws_connect(f"http://127.0.0.1:{port}/ws") as ws:
        while len(out) < n:
            msg = await asyncio.wait_for(ws.receive(), 10.0)
            if msg.type != WSMsgType.TEXT:
                break
            out.append(json.loads(msg.data))
    return out


def test_page_of_a_multipipeline_calibrates_one_camera_at_a_time(tmp_path: Path) -> None:
    multi = MultiPipeline([Pipeline(calibration=c, surface_frames=2) for c in CALS])
    with WebPage(("127.0.0.1", 0), multi, camera_names=["a.npz", "b.npz"],
                 calibration_out=tmp_path / "calibration.json") as page:
        for i in range(2):  # a frame of each camera: their parts are known
            for cam in range(2):
                r = multi.process(frame(cam, i))
                for sink in page.sinks:
                    sink.send(r)
        hello, cams = asyncio.run(first_messages(page.server.port, 2))
        assert hello["type"] == "hello" and cams["type"] == "cameras"
        check(cams)
        assert [c["name"] for c in cams["cameras"]] == ["a.npz", "b.npz"]
        assert all(c["footprint"] is not None for c in cams["cameras"])
        # camera 1 calibrated on the page: its targets, pixels of camera 1 (a new shift)
        targets = cams["cameras"][1]["targets"]
        pairs = [{"depth": [x - 250.0, y], "screen": [x, y]} for x, y in targets]
        code, reply = post(page.server.port, {"screen_wh": list(SCREEN), "pairs": pairs})
        assert code == 400 and "cam" in reply["error"]  # several cameras: say which
        code, reply = post(page.server.port, {"screen_wh": [960, 540], "pairs": pairs, "cam": 1})
        assert code == 400 and "shared screen" in reply["error"]
        code, reply = post(page.server.port, {"screen_wh": list(SCREEN), "pairs": pairs,
                                              "cam": 1})
        assert code == 200 and reply["cam"] == 1, reply
        assert reply["path"] == str(tmp_path / "calibration.cam1.json")
        assert Path(reply["path"]).is_file() and not (tmp_path / "calibration.json").exists()
        sent: list[dict[str, Any]] = []
        page.server.notify = sent.append  # type: ignore[method-assign]
        r = multi.process(frame(1, 2))  # applied by the loop, from camera 1's next frame
        for sink in page.sinks:
            sink.send(r)
        new = multi.calibrations[1].to_screen(np.array([[0.0, 0.0]]))[0]
        assert new == pytest.approx([250.0, 0.0], abs=1e-3)
        assert multi.calibrations[0] is CALS[0]
        [msg] = [m for m in sent if m["type"] == "cameras"]
        check(msg)
        assert msg["cameras"][1]["footprint"][0] == pytest.approx([250.0, 0.0], abs=0.1)
