"""Recording any source to .npz, a PNG folder or a RealSense .db3, and the record/run commands."""

from __future__ import annotations

import json
from collections.abc import Iterator

import numpy as np
import pytest

from depthtouch.cli import main
from depthtouch.errors import SourceError
from depthtouch.sources import NpzSource, open_source, write_npz
from depthtouch.sources.base import SourceBase
from depthtouch.sources.realsense import SourceDisconnected
from depthtouch.sources.record import missing_frames, record
from depthtouch.types import Frame
from synth import Finger, make_recording

K = np.array([[60.0, 0, 31.5], [0, 61.0, 23.5], [0, 0, 1]])


def frames(n: int = 45, t0: float = 7.0, fps: float = 30.0, seed: int = 0) -> list[Frame]:
    rng = np.random.default_rng(seed)
    d = rng.integers(900, 1100, (n, 48, 64)).astype(np.uint16)
    return [Frame(d[i], t0 + i / fps, i, 0.001, K) for i in range(n)]


class ListSource(SourceBase):
    def __init__(self, fr: list[Frame], fail_after: int | None = None,
                 fail: BaseException | None = None) -> None:
        self._fr, self.fail_after, self.fail = fr, fail_after, fail
        self.resolution_wh = (64, 48)
        self.depth_scale_m, self.K, self.fps, self.name = 0.001, K, 30.0, "list"
        self.closed = False

    def frames(self) -> Iterator[Frame]:
        for i, f in enumerate(self._fr):
            if i == self.fail_after:
                raise self.fail or SourceDisconnected("camera unplugged; check the cable")
            yield f

    def close(self) -> None:
        self.closed = True


@pytest.mark.parametrize("target", ["rec.npz", "rec_dir/", "rec.db3"])
def test_record_round_trip(tmp_path, target):  # type: ignore[no-untyped-def]
    if target.endswith(".db3"):
        # an SDK present without its libusb raises ImportError, not ModuleNotFoundError
        pytest.importorskip("pyrealsense2", exc_type=ImportError,
                            reason="pyrealsense2 or its libusb-1.0 is missing")
    fr = frames()
    src = ListSource(fr)
    out = tmp_path / target
    summary = record(src, str(out) if target.endswith("/") else out, seconds=1.0)
    assert src.closed
    assert summary.frames == 30 and summary.missing_frames == 0 and not summary.interrupted
    assert summary.duration_s == pytest.approx(29 / 30) and summary.fps == pytest.approx(30.0)
    back = open_source(out)
    got = list(back.frames())
    assert len(got) == 30
    assert all(np.array_equal(g.depth, f.depth) for g, f in zip(got, fr[:30], strict=True))
    np.testing.assert_allclose([g.timestamp_s for g in got], np.arange(30) / 30, atol=1e-6)
    assert back.depth_scale_m == 0.001
    np.testing.assert_allclose(back.K, K, rtol=1e-6)
    assert sorted(p.name for p in tmp_path.iterdir()) == [out.name]  # no temporaries left


def test_record_converts_recordings_and_stops_at_max_frames(tmp_path):  # type: ignore[no-untyped-def]
    depth, ts = make_recording(10, [[Finger(30, 20)]] * 5, shape=(48, 64), seed=2)
    npz = write_npz(tmp_path / "in.npz", depth, ts, 0.001, K)
    s = record(str(npz), tmp_path / "out.npz", max_frames=12)
    assert s.frames == 12
    out = NpzSource(tmp_path / "out.npz")
    assert np.array_equal(out.read_all(), depth[:12]) and not out.compressed


def test_record_keeps_frames_before_a_disconnect(tmp_path):  # type: ignore[no-untyped-def]
    out = tmp_path / "x.npz"
    with pytest.raises(SourceError, match=r"camera unplugged; check the cable; the 10 frames "
                                          r"before it are in .*x.npz"):
        record(ListSource(frames(), fail_after=10), out)
    assert len(NpzSource(out)) == 10


def test_ctrl_c_keeps_the_recording(tmp_path):  # type: ignore[no-untyped-def]
    out = tmp_path / "x.npz"
    s = record(ListSource(frames(), fail_after=8, fail=KeyboardInterrupt()), out)
    assert s.interrupted and s.frames == 8 and len(NpzSource(out)) == 8
    assert "stopped with Ctrl-C" in s.describe()


def test_a_bug_keeps_no_file(tmp_path):  # type: ignore[no-untyped-def]
    with pytest.raises(ZeroDivisionError):
        record(ListSource(frames(), fail_after=3, fail=ZeroDivisionError()), tmp_path / "x.npz")
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize(
    ("target", "kwargs", "match"),
    [
        ("x.mp4", {}, "unknown recording type '.mp4'; give FILE.npz"),
        ("nodir/x.npz", {}, "does not exist; create it first"),
        ("full", {}, "exists and is not an empty folder"),
        ("x.npz", {"seconds": 0}, "--seconds 0 must be > 0"),
        ("x.npz", {"max_frames": 0}, "must be at least 1"),
    ],
)
def test_record_errors(tmp_path, target, kwargs, match):  # type: ignore[no-untyped-def]
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "a.txt").write_text("x")
    with pytest.raises(SourceError, match=match) as e:
        record(ListSource(frames()), tmp_path / target, **kwargs)
    assert "\n" not in str(e.value)


def test_frame_of_another_size_is_an_error(tmp_path):  # type: ignore[no-untyped-def]
    fr = frames(5)
    fr[3] = Frame(np.zeros((10, 10), np.uint16), fr[3].timestamp_s, 3)
    with pytest.raises(SourceError, match="expected uint16 \\(48, 64\\); record one size"):
        record(ListSource(fr), tmp_path / "x.npz")


@pytest.mark.parametrize(
    ("ts", "want"),
    [([0.0], 0), ([0, 1, 2, 3], 0), ([0, 1, 3, 4], 1), ([0, 1, 2, 6, 7], 3), ([0, 1, 2.4], 0)],
)
def test_missing_frames(ts, want):  # type: ignore[no-untyped-def]
    assert missing_frames(np.asarray(ts, float)) == want


# --- commands ---------------------------------------------------------------------------------
def test_record_command(tmp_path, capsys):  # type: ignore[no-untyped-def]
    depth, ts = make_recording(20, [], shape=(48, 64), seed=1)
    npz = write_npz(tmp_path / "in.npz", depth, ts, 0.001, K)
    rc = main(["record", "--source", str(npz), "--out", str(tmp_path / "o.npz"),
               "--seconds", "0.5"])
    assert rc == 0
    assert "recorded 15 frames" in capsys.readouterr().out
    assert len(NpzSource(tmp_path / "o.npz")) == 15


@pytest.mark.parametrize(
    ("argv", "match"),
    [
        (["record", "--source", "IN", "--out", "o.avi"], "unknown recording type '.avi'"),
        (["record", "--source", "IN", "--out", "o.npz", "--fps", "90"], "apply to cameras"),
        (["run", "--source", "IN", "--preset", "high_accuracy"], "realsense only"),
        (["run", "--source", "missing.npz"], "no such file"),
        (["record", "--source", "IN"], "required: --out"),
    ],
)
def test_command_errors_are_one_line(tmp_path, capsys, argv, match):  # type: ignore[no-untyped-def]
    depth, ts = make_recording(3, [], shape=(48, 64))
    npz = write_npz(tmp_path / "in.npz", depth, ts, 0.001, K)
    argv = [str(npz) if a == "IN" else (str(tmp_path / a) if a.startswith("o.") else a)
            for a in argv]
    try:
        rc = main(argv)
    except SystemExit as e:  # argparse's own usage errors
        rc = int(e.code or 0)
    assert rc == 2
    err = capsys.readouterr().err.strip()
    assert match in err and len(err.splitlines()) == 1


def test_run_command_on_a_recording(tmp_path, capsys):  # type: ignore[no-untyped-def]
    script = [[Finger(40, 40 + i, direction_deg=0)] for i in range(8)] + [[]] * 3
    depth, ts = make_recording(22, script, shape=(96, 128), seed=4, fps=60.0)
    k = np.array([[600.0, 0, 63.5], [0, 600.0, 47.5], [0, 0, 1]])  # synth's scale, cropped
    npz = write_npz(tmp_path / "in.npz", depth, ts, 0.001, k)
    cfg = tmp_path / "c.toml"
    cfg.write_text("[surface]\nlearn_frames = 6\n")
    out = tmp_path / "ev.jsonl"
    rc = main(["run", "--source", str(npz), "--events", str(out), "--config", str(cfg),
               "--countdown", "0.1", "-q"])
    assert rc == 0
    lines = [json.loads(x) for x in out.read_text().splitlines()]
    assert [x["state"] for x in lines].count("down") == 1
    assert min(x["frame"] for x in lines) >= 13  # countdown (7 frames at 60 Hz) + learning (6)
