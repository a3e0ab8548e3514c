"""evaluation/emptystart.py: a rendered recording's empty start shortened, its truth renumbered."""

import numpy as np
import pytest

from depthtouch.errors import ConfigError
from depthtouch.evaluation.emptystart import check_empty_s, frames_to_cut, shorten
from depthtouch.evaluation.suite import SuiteCase, recording_paths
from depthtouch.evaluation.truth import truth_from_dict


def _doc(n: int, empty: int) -> dict:
    frames = [{"frame": i, "t": i / 30.0, "contacts": [], "hovers": []} for i in range(n)]
    frames[60]["contacts"] = [{"id": 1, "x": 10.0, "y": 20.0, "X": 0.0, "Y": 0.0, "Z": 1000.0,
                               "nx": 0.0, "ny": 0.0, "nz": -1.0}]
    return {"format": "depthtouch-truth/1", "scene": "taps", "seed": 1,
            "camera": {"profile": "kinect-v2", "resolution_wh": [4, 3],
                       "K": [[3.0, 0, 1.5], [0, 3.0, 1.0], [0, 0, 1]], "depth_scale": 0.001,
                       "fps": 30.0},
            "empty_frames": empty, "frames": frames,
            "events": [{"kind": "object_placed", "frame": 70, "t": 70 / 30.0}]}


def test_the_first_frames_go_and_the_truth_follows() -> None:
    n, empty = 90, 55
    depth = np.arange(n, dtype=np.uint16)[:, None, None] * np.ones((1, 3, 4), np.uint16)
    ts = np.arange(n) / 30.0
    d2, t2, doc = shorten(depth, ts, _doc(n, empty), 1.0)
    cut = empty - 30  # something comes into view at frame 55; 1.0 s before it is frame 25
    assert frames_to_cut(_doc(n, empty), ts, 1.0) == cut
    assert d2.shape[0] == n - cut and int(d2[0, 0, 0]) == cut and t2[0] == ts[cut]
    assert doc["empty_frames"] == 30 and doc["cut_frames"] == cut
    assert doc["frames"][0]["frame"] == 0 and doc["events"][0]["frame"] == 70 - cut
    truth = truth_from_dict(doc, "t")
    assert truth.n_frames == n - cut and truth.contact_frame.tolist() == [60 - cut]


def test_a_start_already_that_short_stays_as_it_is() -> None:
    ts = np.arange(90) / 30.0
    depth = np.zeros((90, 3, 4), np.uint16)
    doc = _doc(90, 20)
    d2, t2, doc2 = shorten(depth, ts, doc, 1.0)
    assert d2 is depth and t2 is ts and doc2 is doc


@pytest.mark.parametrize("bad", [0.0, 0.1, 11.0, True, "1"])
def test_out_of_range_is_a_one_line_error(bad: object) -> None:
    with pytest.raises(ConfigError, match="empty start"):
        check_empty_s(bad)


def test_a_shortened_case_reads_the_recording_as_rendered() -> None:
    case = SuiteCase("taps", "kinect-v2", 1.0, seed=3)
    short = case.__class__(**{**case.__dict__, "empty_s": 1.0})
    assert short.label.endswith("/empty1/s3") and short.rendered == case
    assert recording_paths(short) == recording_paths(case)
