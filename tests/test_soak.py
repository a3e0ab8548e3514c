"""Soak: a long run at full speed with steady memory, increasing ids, every down matched by one up,
no events lost, and failing peers that never stall the loop.

The default test run replays 10 000 frames; ``make soak`` runs 100 000 (SOAK_FRAMES=100000).
"""

from __future__ import annotations

import json
import os
import resource
import socket
from pathlib import Path

import numpy as np
import pytest

from depthtouch.outputs.jsonl import JsonlSink
from depthtouch.outputs.tuio import TuioSink
from depthtouch.pipeline import Pipeline
from depthtouch.types import Frame
from synth import Finger, render_heights

SHAPE = (240, 320)
K = np.array([[300.0, 0, 159.5], [0, 300.0, 119.5], [0, 0, 1]])
MM_PER_PX = 1000 / 300
FPS = 30.0


def _cycle() -> tuple[list[np.ndarray], int]:
    """One 90-frame cycle of depth frames and the number of contacts in it."""
    rng = np.random.default_rng(5)
    script: list[list[Finger]] = []
    script += [[Finger(100, 120, 90)]] * 10 + [[]] * 8  # a tap
    script += [[Finger(80 + 4 * k, 100 + 2 * k, 60)] for k in range(30)] + [[]] * 8  # a drag
    script += [[Finger(120, 90, 90), Finger(220, 140, 270)]] * 20 + [[]] * 14  # two hands
    frames = []
    for fingers in script:
        hm = render_heights(SHAPE, fingers, MM_PER_PX) if fingers else np.zeros(SHAPE, np.float32)
        d = 1000 - hm + rng.normal(0, 1.5, SHAPE)
        frames.append(np.clip(np.rint(d), 0, 65535).astype(np.uint16))
    return frames, 4


def _rss_kb() -> int:
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1])
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss


def _unreachable_port() -> int:
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()  # nothing listens there: sends get ICMP port unreachable
    return port


def soak(n_frames: int, tmp_path: Path) -> dict:
    empty = np.clip(np.rint(1000 + np.random.default_rng(1).normal(0, 1.5, (45, *SHAPE))), 0, None)
    cycle, contacts_per_cycle = _cycle()
    p = Pipeline(surface_frames=45)
    out = tmp_path / "soak.jsonl"
    rss: list[int] = []
    downs: list[int] = []
    open_ids: set[int] = set()
    ups = 0
    n_events = 0
    with JsonlSink(out) as jsonl, TuioSink("127.0.0.1", _unreachable_port()) as tuio:
        for i in range(n_frames):
            d = empty[i].astype(np.uint16) if i < 45 else cycle[(i - 45) % len(cycle)]
            f = Frame(d, i / FPS, i, 0.001, K)
            result = p.process(f)
            events = result.events
            jsonl.send(result)
            tuio.send(result)
            n_events += len(events)
            for e in events:
                if e.state == "down":
                    assert e.id not in open_ids
                    downs.append(e.id)
                    open_ids.add(e.id)
                elif e.state == "up":
                    open_ids.remove(e.id)
                    ups += 1
                else:
                    assert e.id in open_ids
            if i % max(1, n_frames // 50) == 0:
                rss.append(_rss_kb())
        end = p.finish()
        tail = end.events if end is not None else []
        if end is not None:
            jsonl.send(end)
        n_events += len(tail)
        ups += sum(e.state == "up" for e in tail)
        tuio_errors = tuio.errors
    lines = out.read_text().count("\n")
    return {"downs": downs, "ups": ups, "events": n_events, "lines": lines, "rss": rss,
            "cycles": (n_frames - 45) // len(cycle), "contacts_per_cycle": contacts_per_cycle,
            "tuio_errors": tuio_errors, "last": json.loads(out.read_text().splitlines()[-1])}


def _check(r: dict) -> None:
    downs = r["downs"]
    assert downs == sorted(downs) and len(set(downs)) == len(downs)  # ids increase, never reused
    assert r["ups"] == len(downs)  # every down has exactly one up
    assert r["lines"] == r["events"]  # nothing lost on the way to the file
    # every scripted contact was reported (no id splits, nothing missed)
    expected = r["cycles"] * r["contacts_per_cycle"]
    assert expected <= len(downs) <= expected + r["contacts_per_cycle"]
    warm = r["rss"][len(r["rss"]) * 3 // 10:]  # after a warm-up of 30 % of the run
    assert max(warm) <= 1.05 * warm[0], f"memory grew: {warm}"


def test_soak_reduced(tmp_path: Path) -> None:
    r = soak(int(os.environ.get("SOAK_FRAMES_REDUCED", 10_000)), tmp_path)
    _check(r)


@pytest.mark.slow
def test_soak_full(tmp_path: Path) -> None:
    r = soak(int(os.environ.get("SOAK_FRAMES", 100_000)), tmp_path)
    _check(r)
    print(f"soak: {len(r['downs'])} touches, {r['events']} events, RSS kB {r['rss'][0]} -> "
          f"{r['rss'][-1]}, TUIO send errors counted {r['tuio_errors']}")
