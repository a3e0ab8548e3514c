"""The WebSocket protocol as documented (docs/websocket.md, web/protocol.schema.json): every
message the server sends validates; gestures arrive; height maps only for clients that ask;
``serve --allow-origin``."""

from __future__ import annotations

import asyncio
import json
import re
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("aiohttp")
jsonschema = pytest.importorskip("jsonschema")

from aiohttp import ClientSession, WSMsgType, WSServerHandshakeError  # noqa: E402

from depthtouch.calibration import Calibration  # noqa: E402
from depthtouch.web.server import WebServer  # noqa: E402

SCHEMA_PATH = Path(__file__).parents[2] / "src/depthtouch/web/protocol.schema.json"
SCHEMA = json.loads(SCHEMA_PATH.read_text())
VALIDATOR = jsonschema.Draft202012Validator(SCHEMA)
DEV_ORIGIN = "http://localhost:5173"


def check(message: dict[str, Any]) -> None:
    """The message validates against the protocol, and against its own type's schema."""
    VALIDATOR.validate(message)
    sub = {"$ref": f"#/$defs/{message['type']}", "$defs": SCHEMA["$defs"]}
    jsonschema.Draft202012Validator(sub).validate(message)


def test_schema_is_valid_and_its_examples_validate():
    jsonschema.Draft202012Validator.check_schema(SCHEMA)
    kinds = [d for d in SCHEMA["$defs"].values() if "examples" in d]
    assert len(kinds) == 9  # every message kind has an example
    for d in kinds:
        for ex in d["examples"]:
            check(ex)


@pytest.mark.parametrize("bad", [
    {"type": "hello", "version": 2},
    {"type": "gesture", "kind": "swipe", "frame": 1, "t": 0.1, "ids": [1], "x": 1, "y": 1,
     "space": "depth"},
    {"type": "gesture", "kind": "tap", "frame": 1, "t": 0.1, "ids": [1], "x": 1, "y": 1,
     "space": "depth"},  # a tap without duration_s
    {"type": "frame", "frame": 1, "t": 0.0, "status": {}, "touches": [
        {"id": 1, "state": "hover", "x": 1, "y": 1}]},
    {"type": "subscribe", "height": "yes"},
    {"type": "cameras", "screen_wh": [640, 480], "cameras": [], "overlaps": []},
])
def test_schema_rejects(bad):
    with pytest.raises(jsonschema.ValidationError):
        VALIDATOR.validate(bad)


# --- every message of a served simulation ----------------------------------------------------------
def _start_serve(*extra: str) -> tuple[subprocess.Popen[str], int]:
    proc = subprocess.Popen(
        [sys.executable, "-m", "depthtouch.cli", "serve", "--source", "sim:taps", "--port", "0",
         *extra], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert proc.stdout is not None
    line = proc.stdout.readline()
    m = re.search(r"http://127\.0\.0\.1:(\d+)/", line)
    if m is None:
        proc.kill()
        raise AssertionError(f"serve did not start: {line!r} {proc.stderr.read()!r}")  # type: ignore[union-attr]
    return proc, int(m.group(1))


async def _collect(port: int, origin: str | None, query: str = "", until_taps: int = 2,
                   timeout_s: float = 60.0, send: dict[str, Any] | None = None
                   ) -> tuple[list[dict[str, Any]], int]:
    headers = {"Origin": origin} if origin else {}
    texts: list[dict[str, Any]] = []
    binary = 0
    async with ClientSession() as session, session.ws_connect(
            f"http://127.0.0.1:{port}/ws{query}", headers=headers) as ws:
        if send is not None:
            await ws.send_str(json.dumps(send))
        end = time.monotonic() + timeout_s
        while time.monotonic() < end:
            msg = await asyncio.wait_for(ws.receive(), timeout_s)
            if msg.type == WSMsgType.TEXT:
                texts.append(json.loads(msg.data))
                taps = [m for m in texts if m["type"] == "gesture" and m["kind"] == "tap"]
                if len(taps) >= until_taps:
                    break
            elif msg.type == WSMsgType.BINARY:
                binary += 1
            else:
                break
    return texts, binary


def test_serve_sends_taps_to_an_allowed_origin_and_heights_only_on_request():
    proc, port = _start_serve("--allow-origin", DEV_ORIGIN)
    try:
        texts, binary = asyncio.run(_collect(port, DEV_ORIGIN))
        with pytest.raises(WSServerHandshakeError) as e:
            asyncio.run(_collect(port, "http://localhost:5174", until_taps=0))
        assert e.value.status == 403
        asked, images = asyncio.run(_collect(port, DEV_ORIGIN, "?height=1", until_taps=1))
        late, late_images = asyncio.run(_collect(port, None, "", until_taps=1,
                                                 send={"type": "subscribe", "height": True}))
    finally:
        proc.terminate()
        proc.communicate(timeout=30)
    assert proc.returncode == 0
    assert texts[0]["type"] == "hello" and texts[0]["version"] == 1
    assert texts[0]["height"] is False and binary == 0  # did not ask: no height maps
    assert asked[0]["height"] is True and images >= 1
    assert late_images >= 1  # subscribed by a message after connecting
    taps = [m for m in texts if m["type"] == "gesture" and m["kind"] == "tap"]
    assert len(taps) == 2
    kinds = {m["type"] for m in texts}
    assert {"hello", "frame", "gesture"} <= kinds
    for m in texts + asked + late:
        check(m)
    touches = [t for m in texts if m["type"] == "frame" for t in m["touches"]]
    assert touches and all(0.0 <= t["nx"] <= 1.0 and 0.0 <= t["ny"] <= 1.0 for t in touches)


def test_control_messages_validate():
    """meta, calibration, reset, info and a calibrated frame, as the server sends them."""
    server = WebServer("127.0.0.1", 0)
    sent: list[str] = []
    server.broadcaster.post = lambda kind, payload, t0=None: sent.append(payload)  # type: ignore[method-assign,assignment,misc]
    server.set_resolution((640, 480))
    cal = Calibration(np.array([[3.0, 0, 0], [0, 2.25, 0], [0, 0, 1]]), (1920, 1080), 0.5)
    server.set_calibration(cal)
    server.notify({"type": "reset", "message": "the recording starts again"})
    server.notify({"type": "info", "message": "the recording has finished"})
    from depthtouch.calibration import apply_calibration
    from depthtouch.types import TouchEvent

    # sx, sy come with the events (the pipeline maps them); the sink normalises them
    server.inject(apply_calibration([TouchEvent(3, 0.1, 1, "down", 320.0, 240.0)], cal))
    msgs = [json.loads(s) for s in sent]
    assert [m["type"] for m in msgs] == ["meta", "calibration", "reset", "info", "frame"]
    for m in msgs:
        check(m)
    touch = msgs[-1]["touches"][0]
    assert (touch["sx"], touch["sy"]) == (960.0, 540.0)
    assert (touch["nx"], touch["ny"]) == (0.5, 0.5)  # of the calibrated screen
    check({**server._hello(), "height": False})


@pytest.mark.parametrize("bad", ["localhost:5173", "http://localhost:5173/app", "ftp://x", ""])
def test_allow_origin_must_be_an_origin(cli, bad):
    r = cli("serve", "--source", "sim:taps", "--port", "0", "--allow-origin", bad)
    assert r.rc == 2 and "--allow-origin" in r.err and len(r.err_lines) == 1
