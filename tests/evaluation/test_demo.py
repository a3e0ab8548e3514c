"""The demo report (``depthtouch demo``) and the accuracy tables it prints."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from depthtouch.evaluation.metrics import Truth, evaluate, truth_from_dict
from depthtouch.evaluation.report import (
    COLUMNS,
    metrics_html,
    metrics_markdown,
    metrics_table,
    plot_paths,
    table_rows,
)
from depthtouch.evaluation.summary import summarize
from depthtouch.types import TouchEvent


def _truth() -> Truth:
    K = [[500.0, 0, 320.0], [0, 500.0, 240.0], [0, 0, 1]]
    frames = [{"frame": f, "t": f / 30, "hovers": [],
               "contacts": [{"id": 1, "x": 300.0 + f, "y": 200.0, "X": (f - 20) * 2.0,
                             "Y": -80.0, "Z": 1000.0, "nx": 0, "ny": 0, "nz": -1}]
               if 5 <= f < 20 else []} for f in range(25)]
    return truth_from_dict({"format": "depthtouch-truth/1", "scene": "t",
                            "camera": {"K": K, "fps": 30, "resolution_wh": [640, 480]},
                            "frames": frames})


def _events() -> list[TouchEvent]:
    ev = [TouchEvent(f, f / 30, 3, "down" if f == 6 else "move", 300.5 + f, 200.0)
          for f in range(6, 20)]
    return [*ev, TouchEvent(20, 20 / 30, 3, "up", 319.5, 200.0)]


def test_tables_have_one_row_per_entry_and_dash_for_nan() -> None:
    m = {"a": summarize([evaluate(_truth(), _events())]),
         "empty": summarize([evaluate(_truth(), [])])}
    rows = table_rows(m)
    assert [r[0] for r in rows] == ["a", "empty"]
    assert all(len(r) == len(COLUMNS) + 1 for r in rows)
    assert "-" in rows[1]  # no matches: no error
    md = metrics_markdown(m)
    assert md.count("\n") == 3 and md.startswith("| case |")
    assert metrics_html(m).count("<tr>") == 3
    assert metrics_table(m).row_count == 2


def test_plot_paths_writes_a_png(tmp_path: Path) -> None:
    p = plot_paths(_truth(), _events(), tmp_path / "p.png", title="t")
    assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_demo_writes_report(tmp_path: Path) -> None:
    pytest.importorskip("depthtouch.sim")
    from depthtouch.evaluation.report import run_demo

    res = run_demo(tmp_path / "rep", scenes=("taps",), camera="kinect-v2")
    out = tmp_path / "rep"
    html = res.index.read_text()
    assert res.index == out / "index.html"
    for name in ("taps-depth.png", "taps-height.png", "taps-paths.png", "taps.events.jsonl"):
        assert (out / name).is_file(), name
        assert name in html
    lines = (out / "taps.events.jsonl").read_text().splitlines()
    assert lines and {"frame", "id", "state", "x", "y"} <= set(json.loads(lines[0]))
    m = res.metrics["taps"]
    assert m.contacts > 0
    assert m.contact_recall >= 0.9
    assert math.isfinite(m.error_median_mm)
    assert "<table>" in html and "taps" in html


def test_cli_demo_rejects_a_file_as_out(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from depthtouch.cli import main

    f = tmp_path / "file"
    f.write_text("x")
    assert main(["demo", "--out", str(f), "--scenes", "taps"]) == 2
    err = capsys.readouterr().err
    assert "not a folder" in err and err.count("\n") == 1


def test_cli_demo_unknown_scene_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    pytest.importorskip("depthtouch.sim")
    from depthtouch.cli import main

    assert main(["demo", "--out", str(tmp_path / "r"), "--scenes", "nosuch"]) == 2
    err = capsys.readouterr().err
    assert "nosuch" in err and err.count("\n") == 1


def test_height_map_plot(tmp_path: Path) -> None:
    from depthtouch.evaluation.report import plot_height_map

    h = np.zeros((48, 64), np.float32)
    h[10:20, 10:20] = 12.0
    h[0, 0] = np.nan
    p = plot_height_map(h, tmp_path / "h.png", touches_xy=np.array([[15.0, 15.0]]),
                        truth_xy=np.array([[14.0, 15.0]]))
    assert p.stat().st_size > 1000
