"""A surface that ends inside the view (sim/edge.py, render_scene(edge_mm=))."""

import json

import numpy as np
import pytest
from scipy.ndimage import binary_dilation, binary_erosion

from depthtouch.errors import ConfigError
from depthtouch.evaluation.suite import SuiteCase, load_suite
from depthtouch.sim import render_scene
from depthtouch.sim.edge import check_edge
from depthtouch.sim.geometry import Rays
from simcheck import check_suite_group_key


@pytest.mark.parametrize("bad", [-1.0, 50.0, 2000.0, True, "700", None])
def test_a_bad_drop_is_a_one_line_error(bad):
    with pytest.raises(ConfigError, match=r"edge drop .* out of range; allowed 0 \(no edge\) or "
                                          r"\[100, 1500\] mm"):
        check_edge(bad)


def _beyond(rec) -> np.ndarray:
    """The pixels beyond the truth's edge (from the truth document's surface)."""
    from depthtouch.sim.geometry import make_surface

    s = rec.truth["surface"]
    surf = make_surface(s["kind"], s["distance_m"], s["tilt_deg"])
    h, w = rec.depth.shape[1:]
    rays = Rays(rec.K, (w, h))
    z = surf.depth_map(rays).astype(np.float64)
    st = surf.st_of(np.stack([rays.xn * z, rays.yn * z, z], -1).reshape(-1, 3))
    e = rec.truth["edge"]
    return (st @ np.asarray(e["dir_st"]) < e["c_mm"]).reshape(h, w)


@pytest.mark.parametrize("camera", ["kinect-v2", "realsense-d435"])
def test_beyond_the_edge_lies_the_floor_and_the_touches_stay_as_they_were(camera):
    kw = dict(camera=camera, seed=1, resolution_scale=0.5, distance_m=1.3)
    full = render_scene("taps", **kw)
    rec = render_scene("taps", edge_mm=700.0, **kw)
    e = rec.truth["edge"]
    assert e["drop_mm"] == 700.0 and 40.0 <= e["margin_mm"] <= 150.0
    assert 0.02 < e["share_beyond"] < 0.6 and "edge" not in full.truth
    beyond = _beyond(rec)
    assert abs(beyond.mean() - e["share_beyond"]) < 0.01
    first = rec.depth[0].astype(np.float64)  # empty: the surface and the floor only
    ok = (first > 0) & (full.depth[0] > 0)
    # away from the edge: the floor ~700 mm farther (a plane seen head-on), the table as before
    far, near = binary_erosion(beyond, iterations=4), binary_erosion(~beyond, iterations=4)
    step = np.median(first[far & ok]) - np.median(full.depth[0][far & ok].astype(np.float64))
    assert 690.0 < step < 710.0
    assert abs(np.mean(first[near & ok]) - np.mean(full.depth[0][near & ok])) < 1.0
    # every contact lies on the table, behind the margin
    for f, g in zip(rec.truth["frames"], full.truth["frames"]):
        assert f["contacts"] == g["contacts"]
    px = np.array([(c["x"], c["y"]) for f in rec.truth["frames"] for c in f["contacts"]])
    assert px.size and not beyond[np.rint(px[:, 1]).astype(int), np.rint(px[:, 0]).astype(int)].any()


def test_the_step_has_artefacts_every_frame_at_a_tof_camera():
    """Flying pixels along the edge are drawn again each frame, not once."""
    rec = render_scene("taps", camera="kinect-v2", seed=1, resolution_scale=0.5, distance_m=1.3,
                       edge_mm=700.0)
    beyond = _beyond(rec)
    band = binary_dilation(beyond, iterations=2) & ~binary_erosion(beyond, iterations=2)
    d = rec.depth[:40].astype(np.float64)[:, band]
    # between the table (1300) and the floor (2000): mixed pixels, at other pixels each frame
    mid = (d > 1400) & (d < 1900)
    assert mid.sum() > 10 and (mid.sum(0) > 0).sum() > 2 * mid.sum(0).max()


def test_suites_name_and_render_the_option(tmp_path):
    case = SuiteCase("taps", "kinect-v2", 1.0, seed=3, edge_mm=700.0)
    assert case.label.endswith("/edge700/s3") and case.render_kwargs()["edge_mm"] == 700.0
    assert "edge_mm" not in SuiteCase("taps", "kinect-v2", 1.0).render_kwargs()
    hard = load_suite("hard")
    s = hard.with_edge(500.0)
    assert all(c.edge_mm == 500.0 for c in s.cases) and hard.with_edge(None) is hard
    assert s.cases[0].cache_key() != hard.cases[0].cache_key()
    with pytest.raises(ConfigError, match="out of range"):
        hard.with_edge(20.0)
    check_suite_group_key(tmp_path, "edge_mm", "600", 600.0, "60", "group group0: edge drop 60")


def test_the_commands_take_the_option_and_refuse_it_where_it_means_nothing(tmp_path, capsys):
    from depthtouch.cli import main

    out, truth = tmp_path / "e.npz", tmp_path / "e.json"
    assert main(["sim", "taps", "--camera", "kinect-v2", "--resolution-scale", "0.5",
                 "--edge-mm", "700", "--out", str(out), "--truth", str(truth), "-q"]) == 0
    assert json.loads(truth.read_text())["edge"]["drop_mm"] == 700.0
    assert main(["sim", "taps", "--views", "2", "--edge-mm", "700",
                 "--out", str(tmp_path / "v"), "--truth", str(tmp_path / "v.json")]) == 2
    assert "--edge-mm applies to one camera" in capsys.readouterr().err
    assert main(["eval", str(out), "--truth", str(truth), "--edge-mm", "700"]) == 2
    assert "--edge-mm needs --suite NAME" in capsys.readouterr().err
