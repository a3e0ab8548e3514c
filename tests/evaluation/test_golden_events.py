"""The sensor reports what it reported before the restructuring, event for event.

``tests/golden/default_suite_events.json`` holds digests of the events of every case of the
default suite, replayed with a screen calibration, made by the code before the package was
reorganised (``golden_events.py``). ``X``, ``Y``, ``Z`` are compared apart: they now come from
the surface as it is now (adapted), not as first learned, and so may differ once the surface
has followed a drift or absorbed an object. A change meant to change the events regenerates the
file and says so.
"""

from __future__ import annotations

import json

import pytest
from golden_events import GOLDEN, case_digest, suite_cases

GOLDEN_DIGESTS = json.loads(GOLDEN.read_text())
CASES = {c.label: c for c in suite_cases()}
QUICK = ["taps/realsense-d435/1m/s1", "drags/kinect-v2/1m/s1", "bump/kinect-v1/1m/s1",
         "object/kinect-v1/1m/s1"]


def _check(label: str) -> None:
    got, want = case_digest(CASES[label]), GOLDEN_DIGESTS[label]
    assert got["events"] == want["events"], label
    assert got["sha256_no_xyz"] == want["sha256_no_xyz"], label


def test_golden_covers_the_default_suite() -> None:
    assert set(GOLDEN_DIGESTS) == set(CASES)


@pytest.mark.parametrize("label", QUICK)
def test_same_events_as_before(label: str) -> None:
    _check(label)


@pytest.mark.slow
@pytest.mark.parametrize("label", sorted(set(CASES) - set(QUICK)))
def test_same_events_as_before_whole_suite(label: str) -> None:
    _check(label)
