"""``replay`` paces itself with --tuio (apps see the touches as they happened) unless told not to,
and says so; --realtime paces any replay."""

from __future__ import annotations

from typing import Any

import pytest

from depthtouch import cli


@pytest.mark.parametrize(("args", "paced", "note"), [
    ([], None, False),
    (["--tuio", "127.0.0.1:3333"], 1.0, True),
    (["--tuio", "127.0.0.1:3333", "--no-realtime"], None, False),
    (["--realtime"], 1.0, False),
])
def test_replay_pace(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str],
                     args: list[str], paced: float | None, note: bool) -> None:
    seen: dict[str, Any] = {}

    class Summary:
        def describe(self) -> str:
            return "done"

    def fake_replay(recording: str, **kw: Any) -> Summary:
        seen.update(kw)
        return Summary()

    monkeypatch.setattr("depthtouch.replay.replay", fake_replay)
    assert cli.main(["replay", "rec.npz", *args]) == 0
    assert seen["realtime"] == paced
    assert ("own pace for --tuio" in capsys.readouterr().err) is note
