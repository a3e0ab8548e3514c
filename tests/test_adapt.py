"""The surface follows a changing room: objects, drift and bumps; fingers are never absorbed."""

import numpy as np
import pytest

from depthtouch.config import PipelineConfig
from depthtouch.pipeline import Pipeline
from depthtouch.types import Frame
from synth import K_640, Finger, render_heights

MM_PER_PX = 1000 / 600
FPS = 30.0


def frames(script, *, seed=0, noise=1.5, plane=None):
    """Yield Frames: 45 empty ones, then one per script entry (a callable k -> heights)."""
    rng = np.random.default_rng(seed)
    bank = rng.normal(0, noise, (17, 480, 640)).astype(np.float32)  # cycled: cheap, still noisy
    for i in range(45 + len(script)):
        hm = np.zeros((480, 640), np.float32) if i < 45 else script[i - 45](i - 45)
        base = 1000.0 if plane is None else plane(i)
        d = base - hm + bank[i % 17]
        yield Frame(np.clip(np.rint(d), 0, 65535).astype(np.uint16), i / FPS, i, 0.001, K_640)


def run(script, config=None, **kw):
    p = Pipeline(config, surface_frames=45)
    log = [(f, p.process(f)) for f in frames(script, **kw)]
    return p, log


def box(hm, x0, y0, x1, y1, height):
    hm = hm.copy()
    hm[y0:y1, x0:x1] = np.maximum(hm[y0:y1, x0:x1], height)
    return hm


def test_object_put_down_is_absorbed_and_removal_restores():
    empty = np.zeros((480, 640), np.float32)
    with_box = box(empty, 250, 200, 350, 260, 60.0)  # a 60 mm tall box
    script = [lambda k: with_box] * 90 + [lambda k: empty] * 90  # 3 s on, 3 s off
    p, log = run(script)
    assert p._bounds is not None
    # after the box stood 3 s it was surface; after 3 s without it the table is back
    s = p._bounds.surface_mm
    assert abs(float(s[230, 300]) - 1000.0) < 3.0
    assert not any(evs for _, evs in log)


def test_object_becomes_surface_within_two_seconds():
    empty = np.zeros((480, 640), np.float32)
    with_box = box(empty, 250, 200, 350, 260, 60.0)
    p = Pipeline(surface_frames=45)
    t_absorbed = None
    for f in frames([lambda k: with_box] * 120):
        p.process(f)
        if (p._bounds is not None and f.index >= 45 and t_absorbed is None
                and np.median(p._bounds.surface_mm[205:255, 255:345]) < 950):
            t_absorbed = (f.index - 45) / FPS
    assert t_absorbed is not None and t_absorbed <= 2.0


def test_finger_held_still_ten_seconds_is_never_absorbed():
    f = Finger(320, 240, 90)
    hm = render_heights((480, 640), [f], MM_PER_PX)
    script = [lambda k: hm] * int(10 * FPS)
    p, log = run(script)
    events = [e for _, evs in log for e in evs]
    assert {e.id for e in events} == {1}
    assert [e.state for e in events].count("down") == 1
    assert all(e.state != "up" for e in events)
    last = [e for e in log[-1][1]]
    assert last and np.hypot(last[0].x - f.x, last[0].y - f.y) * MM_PER_PX < 3.0


def test_slow_drift_is_absorbed():
    # the table comes 3 mm closer over 10 s (a thermal drift is slower still), then stays
    n_drift = int(10 * FPS)
    plane = lambda i: 1000.0 - min(max(0, i - 45), n_drift) * 3.0 / n_drift  # noqa: E731
    empty = np.zeros((480, 640), np.float32)
    p, log = run([lambda k: empty] * int(20 * FPS), plane=plane)
    assert p._bounds is not None and p.stats.relearns == 0
    assert abs(float(np.median(p._bounds.surface_mm)) - 997.0) < 1.0
    assert not any(evs for _, evs in log)


def test_camera_bump_relearns_the_surface():
    # the camera moves: the table is 40 mm farther and tilted from frame 45 + 30 on
    yy = np.arange(480, dtype=np.float32)[:, None]
    shifted = np.broadcast_to(-40.0 - 0.05 * (yy - 240), (480, 640)).astype(np.float32)
    script = [lambda k: np.zeros((480, 640), np.float32)] * 30 + [lambda k: shifted] * 150
    p, log = run(script)
    assert p.stats.relearns == 1
    assert p.surface is not None
    assert abs(float(np.median(p._bounds.surface_mm)) - 1040.0) < 3.0
    assert not any(evs for _, evs in log)


@pytest.mark.parametrize("enabled", [False, True])
def test_adaptation_can_be_switched_off(enabled):
    empty = np.zeros((480, 640), np.float32)
    with_box = box(empty, 250, 200, 350, 260, 60.0)
    cfg = PipelineConfig().replace(adapt={"enabled": enabled})
    p, _ = run([lambda k: with_box] * 90, config=cfg)
    assert (float(p._bounds.surface_mm[230, 300]) < 950) is enabled
