"""What the band held near a contact no point came near (evaluation.notes.band_states)."""

from __future__ import annotations

import numpy as np
import pytest

from depthtouch.config import RegionConfig
from depthtouch.evaluation.metrics import BAND_STATES, truth_from_dict
from depthtouch.evaluation.notes import band_states, contact_pixels
from depthtouch.surface.bounds import band_bounds
from depthtouch.surface.model import SurfaceModel

H, W = 120, 160
FX = 500.0  # a flat surface at 1 m: 2 mm per px


def flat_bounds(open_px: int = 3):
    d = np.full((H, W), 1000.0, np.float32)
    K = np.array([[FX, 0, W / 2], [0, FX, H / 2], [0, 0, 1.0]])
    s = SurfaceModel(d, d, d, d, np.full((H, W), 0.5, np.float32), np.ones((H, W), bool),
                     "median", 0.001, K, 30)
    return band_bounds(s, RegionConfig(open_px=open_px))


def frame_with(heights: dict[tuple[int, int, int, int], float]) -> np.ndarray:
    """The flat surface's frame with boxes (rows y0:y1, columns x0:x1) at these heights."""
    depth = np.full((H, W), 1000, np.uint16)
    for (y0, y1, x0, x1), h in heights.items():
        depth[y0:y1, x0:x1] = int(round(1000 - h))
    return depth


@pytest.mark.parametrize(("heights", "want"), [
    ({}, "nothing in the band"),
    # a finger 40 mm up: above the band (Tu 25 mm)
    ({(55, 65, 75, 85): 40.0}, "nothing in the band"),
    # a crescent 2 px deep in the band: the 3x3 opening erases it
    ({(58, 60, 76, 84): 10.0}, "band erased by the opening"),
    # a tip 5x5 px in the band: it survives the opening
    ({(58, 63, 78, 83): 10.0}, "a region without a point"),
    # band pixels farther than 10 mm (5 px) from the contact do not count
    ({(58, 63, 90, 95): 10.0}, "nothing in the band"),
])
def test_what_the_band_holds_near_a_contact(heights: dict, want: str) -> None:
    b = flat_bounds()
    assert b.mm_per_px == pytest.approx(2.0) and b.open_px == 3
    assert band_states(frame_with(heights), b, np.array([[80.0, 60.0]])) == [want]
    assert want in BAND_STATES


def test_a_probe_at_the_image_edge_and_several_probes() -> None:
    b = flat_bounds()
    depth = frame_with({(0, 5, 0, 5): 10.0})
    got = band_states(depth, b, np.array([[0.0, 0.0], [80.0, 60.0], [159.0, 119.0]]))
    assert got == ["a region without a point", "nothing in the band", "nothing in the band"]


def test_contact_pixels_by_frame() -> None:
    from test_evaluation import contact, doc

    t = truth_from_dict(doc(10, {3: [contact(1, 10, 20), contact(2, 30, 40)],
                                 5: [contact(1, 11, 21)]}))
    px = contact_pixels(t)
    assert sorted(px) == [3, 5]
    assert np.allclose(px[3], [[10, 20], [30, 40]]) and np.allclose(px[5], [[11, 21]])


def test_the_local_erosion_is_the_sensors_own() -> None:
    """On random frames, an opened part lies near a probe exactly when the sensor's own
    eroded band (regions.band_core) has a pixel within the same distance."""
    from depthtouch.touch.regions import band_core

    b = flat_bounds()
    rng = np.random.default_rng(5)
    r = 5  # 10 mm at 2 mm per px
    for _ in range(40):
        heights = {}
        for _ in range(8):  # boxes anywhere, the image's edges too
            y, x = int(rng.integers(-2, H - 2)), int(rng.integers(-2, W - 2))
            heights[(max(y, 0), y + int(rng.integers(3, 7)), max(x, 0),
                     x + int(rng.integers(3, 7)))] = float(
                rng.uniform(2, 40))
        depth = frame_with(heights)
        core = band_core(depth, b) > 0
        probes = np.vstack([rng.uniform(0, [W - 1, H - 1], (8, 2)),
                            [[0.0, 0.0], [W - 1.0, H - 1.0], [0.0, H / 2]]])
        for (x, y), state in zip(probes, band_states(depth, b, probes), strict=True):
            cx, cy = int(round(x)), int(round(y))
            near = core[max(cy - r, 0):cy + r + 1, max(cx - r, 0):cx + r + 1].any()
            assert near == (state == "a region without a point")


def test_outside_the_image_counts_as_band_as_in_the_sensors_erosion() -> None:
    """A part 2 px deep along the image's top edge survives the sensor's opening (outside the
    image counts as in); inside the image the same part is erased."""
    from depthtouch.touch.regions import band_core

    b = flat_bounds()
    edge = frame_with({(0, 2, 70, 90): 10.0})
    assert (band_core(edge, b)[:5, 75:85] > 0).any()
    assert band_states(edge, b, np.array([[80.0, 0.0]])) == ["a region without a point"]
    inside = frame_with({(30, 32, 70, 90): 10.0})
    assert not (band_core(inside, b)[25:35, 75:85] > 0).any()
    assert band_states(inside, b, np.array([[80.0, 30.0]])) == ["band erased by the opening"]
