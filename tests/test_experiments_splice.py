"""benchmarks/experiments.py: regenerating the tables keeps the hand-written sections."""

from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

import experiments  # noqa: E402

OLD = """# Accuracy

old head

## 0. Where it stands

by hand

## 1. The default suite

old table

## 6. The hard suite

old hard

## 7. Session by session

by hand too
"""


def test_a_whole_run_keeps_only_the_hand_written_sections() -> None:
    new = ["## 1. The default suite", "", "new table", ""]
    out = "\n".join(experiments._splice(OLD, new, keep=experiments.HAND_WRITTEN))
    assert out.index("## 0.") < out.index("## 1.") < out.index("## 7.")
    assert "by hand" in out and "by hand too" in out and "new table" in out
    assert "old table" not in out
    assert "old hard" not in out  # a generated section the run did not write is not kept
    assert "old head" not in out  # the head is the generator's own


def test_only_keeps_every_section_it_did_not_write() -> None:
    new = ["## 6. The hard suite", "", "new hard", ""]
    out = "\n".join(experiments._splice(OLD, new))
    assert "old table" in out and "new hard" in out and "old hard" not in out
    assert out.index("## 0.") < out.index("## 1.") < out.index("## 6.") < out.index("## 7.")
