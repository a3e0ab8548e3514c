"""The simulator's body (``render_scene(body=True)``): every arm goes on past the shoulder into a
body that leaves the view, as a person's does. Without it the arm ends at the shoulder, and a
camera from about 1.3 m sees the whole arm inside the image (docs/simulator.md); nothing else
of a seed's scene changes."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from depthtouch.cli import main
from depthtouch.errors import ConfigError
from depthtouch.evaluation.suite import suite_from_dict
from depthtouch.sim import render_scene

FAR = {"camera": "kinect-v2-hard", "distance_m": 2.0, "tilt_deg": 10.0, "seed": 3, "fps": 6.0}


def _at_border(labels: np.ndarray) -> np.ndarray:
    """Per frame: whether anything the scene put in front of the surface touches the border."""
    a = labels > 0
    return a[:, 0, :].any(1) | a[:, -1, :].any(1) | a[:, :, 0].any(1) | a[:, :, -1].any(1)


def test_a_far_camera_sees_the_arm_whole_without_the_body_and_cut_by_the_border_with_it(
) -> None:
    plain = render_scene("hold", keep_labels=True, **FAR)
    body = render_scene("hold", keep_labels=True, body=True, **FAR)
    assert plain.labels is not None and body.labels is not None
    busy = (plain.labels > 0).reshape(len(plain.labels), -1).any(1)
    assert busy.sum() > 20
    assert _at_border(plain.labels)[busy].mean() < 0.2  # the hold: the arm wholly in view
    assert _at_border(body.labels)[busy].all()
    # the same scene but for the body: same truth, the same empty frames
    assert plain.truth == body.truth
    empty = plain.truth["empty_frames"]
    assert empty > 0 and np.array_equal(plain.depth[:empty], body.depth[:empty])


def test_a_resting_forearm_goes_on_into_a_body() -> None:
    kw = {**FAR, "distance_m": 1.3, "tilt_deg": 6.5}
    plain = render_scene("rest", keep_labels=True, **kw)
    body = render_scene("rest", keep_labels=True, body=True, **kw)
    assert plain.labels is not None and body.labels is not None
    rest = 104  # hardscenes.LABEL_REST_HAND
    on = (plain.labels == rest).reshape(len(plain.labels), -1).any(1)
    assert on.sum() > 5
    a_plain = _at_border(np.where(plain.labels == rest, 1, 0))[on]
    a_body = _at_border(np.where(body.labels == rest, 1, 0))[on]
    assert a_body.all() and a_body.sum() > a_plain.sum()


@pytest.mark.parametrize("v", [1, "yes", None])
def test_body_must_be_a_bool(v: object) -> None:
    with pytest.raises(ConfigError, match=r"body .* must be true or false"):
        render_scene("taps", body=v, **FAR)  # type: ignore[arg-type]


def test_a_suite_group_sets_the_body_and_names_it() -> None:
    group = {"name": "g", "scenes": ["taps"], "cameras": ["kinect-v2-hard"],
             "distances_m": [1.0], "seeds": [1]}
    (case,) = suite_from_dict({"group": [{**group, "body": True}]}).cases
    assert case.body and "/body/" in case.label and case.render_kwargs()["body"] is True
    (plain,) = suite_from_dict({"group": [group]}).cases
    assert "body" not in plain.render_kwargs() and "/body" not in plain.label
    assert plain.cache_key() != case.cache_key()
    with pytest.raises(ConfigError, match=r"group g: body = 'yes' must be true or false"):
        suite_from_dict({"group": [{**group, "body": "yes"}]})


def test_sim_cli_takes_body_and_refuses_it_with_views(tmp_path: Path, capsys) -> None:
    out, truth = tmp_path / "s.npz", tmp_path / "s.json"
    assert main(["sim", "taps", "--camera", "kinect-v2", "--fps", "4", "--body",
                 "--out", str(out), "--truth", str(truth), "-q"]) == 0
    assert out.is_file() and truth.is_file()
    assert main(["sim", "taps", "--views", "2", "--body", "--out",
                 str(tmp_path / "v"), "--truth", str(tmp_path / "v.json")]) == 2
    assert "--body applies to one camera" in capsys.readouterr().err
