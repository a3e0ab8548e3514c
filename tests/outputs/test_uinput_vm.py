"""``depthtouch play EVENTS --uinput`` inside a real Linux kernel (QEMU, software emulation).

The events come from a calibrated replay of a simulated recording, made on the host. The guest
(tests/vm/guest.py) prints what the kernel delivers on the new /dev/input/eventN; this test
rebuilds the contacts from it (tracking ids, positions, releases) and compares them with the
events file. Skipped, saying why, only when QEMU, busybox-static or the kernel package can't be
had (.ci/run installs them). The boot time is measured by benchmarks/uinput_vm.py, not here.
"""

from __future__ import annotations

import math
import shlex
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest

from depthtouch.outputs.jsonl import read_events
from vm.uinput_vm import REPO, Unavailable, boot, ensure_assets

GUEST = REPO / "tests" / "vm" / "guest.py"
SCREEN_WH = (1920, 1080)
SLOTS = 10  # the device's default
# reports with a contact down before the guest sends SIGTERM: in the multitouch replay three
# contacts are down from frame 88-90 and the fourth comes at the 25th such report (frame 113);
# the kill must land well before it (the emulated guest takes a few frames to deliver it)
SIGTERM_AFTER_REPORTS = 10
EV_SYN, EV_KEY, EV_ABS = 0, 1, 3
ABS_MT_SLOT, ABS_MT_POSITION_X, ABS_MT_POSITION_Y, ABS_MT_TRACKING_ID = 0x2F, 0x35, 0x36, 0x39
BTN_TOUCH = 0x14A


@dataclass
class Contact:
    tracking_id: int
    positions: list[tuple[int, int]] = field(default_factory=list)
    released: bool = False
    release_rank: int = -1  # 0 for the first contact released, 1 for the next...


def contacts_from_kernel(stream: list[tuple[int, int, int]]) -> tuple[list[Contact], int]:
    """What a protocol-B reader sees: contacts in the order of their tracking ids, each with its
    distinct positions, and the final BTN_TOUCH. Slot values start at 0; the kernel sends only
    changed values, so a value not repeated is the slot's previous one."""
    slot = 0
    xy: dict[int, list[int]] = {}
    live: dict[int, Contact] = {}
    done: list[Contact] = []
    touch = 0

    def note(s: int) -> None:
        c = live.get(s)
        if c is not None:
            p = (xy[s][0], xy[s][1])
            if not c.positions or c.positions[-1] != p:
                c.positions.append(p)

    for typ, code, value in stream:
        if typ == EV_ABS and code == ABS_MT_SLOT:
            slot = value
        elif typ == EV_ABS and code in (ABS_MT_POSITION_X, ABS_MT_POSITION_Y):
            xy.setdefault(slot, [0, 0])[code - ABS_MT_POSITION_X] = value
        elif typ == EV_ABS and code == ABS_MT_TRACKING_ID:
            old = live.get(slot)
            if old is not None:
                xy.setdefault(slot, [0, 0])
                note(slot)  # an up's last position travels in its release report
                del live[slot]
                old.released, old.release_rank = True, len(done)
                done.append(old)
            if value >= 0:
                live[slot] = Contact(value)
        elif typ == EV_KEY and code == BTN_TOUCH:
            touch = value
        elif typ == EV_SYN and code == 0:
            for s in list(live):
                xy.setdefault(s, [0, 0])
                note(s)
    contacts = sorted([*done, *live.values()], key=lambda c: c.tracking_id)
    return contacts, touch


@dataclass
class Expected:
    """From the events file: each touch id (in the order of its down) -> its screen positions,
    one per event, clipped to the screen like the device's axes; the ids in the order of their
    ups; how many downs found all slots taken (those never reach the device)."""

    positions: dict[int, list[tuple[float, float]]]
    ups: list[int]
    dropped: int


def expected_touches(events_path: Path) -> Expected:
    want = Expected({}, [], 0)
    down: set[int] = set()
    dropped: set[int] = set()
    for e in read_events(events_path):
        sx = min(max(float(e.extra["sx"]), 0.0), SCREEN_WH[0] - 1.0)
        sy = min(max(float(e.extra["sy"]), 0.0), SCREEN_WH[1] - 1.0)
        if e.state == "down":
            assert e.id not in want.positions and e.id not in dropped, "an id went down twice"
            if len(down) == SLOTS:
                dropped.add(e.id)
                continue
            down.add(e.id)
            want.positions[e.id] = []
        if e.id in dropped:
            continue
        want.positions[e.id].append((sx, sy))
        if e.state == "up":
            down.discard(e.id)
            want.ups.append(e.id)
    want.dropped = len(dropped)
    return want


def rounded(want: list[tuple[float, float]]) -> list[tuple[int, int]]:
    """The distinct whole-pixel positions of a touch, in order (what a device that writes only
    changes can show)."""
    out: list[tuple[int, int]] = []
    for x, y in want:
        p = (math.floor(x + 0.5), math.floor(y + 0.5))
        if not out or out[-1] != p:
            out.append(p)
    return out


def compare(contact: Contact, want: list[tuple[float, float]]) -> float:
    """The largest distance (screen px, per axis) between each event's ``sx``, ``sy`` and the
    position the kernel delivered for it, walking both in order; fails when the kernel shows a
    position that is not the next event's. For a contact cut short (SIGTERM), its events so far."""
    err, j = 0.0, 0
    kernel = contact.positions
    for x, y in want:
        p = (math.floor(x + 0.5), math.floor(y + 0.5))
        if p != kernel[j]:
            j += 1
            if j == len(kernel):
                break
            assert p == kernel[j], f"tracking id {contact.tracking_id}: {kernel[j]}, want {p}"
        err = max(err, abs(kernel[j][0] - x), abs(kernel[j][1] - y))
    return err


@pytest.fixture(scope="module")
def assets():
    pytest.importorskip("evdev", reason="python-evdev missing; pip install -e '.[uinput]'")
    try:
        return ensure_assets()
    except Unavailable as e:
        pytest.skip(f"no VM: {e}")


@pytest.fixture(scope="module")
def calibrated_events(tmp_path_factory):
    """A calibrated replay of the simulated multitouch scene: 5 touches at once (until session 5
    the sensor added a dozen false ones as the arms left, which overflowed the 10 slots; the
    overflow has its own test in test_uinput.py)."""
    from depthtouch.calibration import Calibration, save_calibration
    from depthtouch.cli import main

    d = tmp_path_factory.mktemp("uinput_vm")
    rec, cal, ev = d / "multitouch.npz", d / "cal.json", d / "events.jsonl"
    assert main(["sim", "multitouch", "--out", str(rec), "--truth", str(d / "truth.json"),
                 "--camera", "realsense-d435", "-q"]) == 0
    w, h = 848, 480  # realsense-d435 depth image -> a 1920x1080 screen, with some perspective
    H = np.array([[SCREEN_WH[0] / w, 0.02, 3.0], [0.01, SCREEN_WH[1] / h, -2.0],
                  [1e-5, 2e-5, 1.0]])
    save_calibration(Calibration(H, SCREEN_WH, 0.0), cal)
    assert main(["replay", str(rec), "--calibration", str(cal), "--events", str(ev), "-q"]) == 0
    return ev, cal


def _section(lines: list[str], name: str) -> list[str]:
    start = lines.index(f"DT-VM: run {name}")
    end = next((i for i in range(start + 1, len(lines)) if lines[i].startswith("DT-VM: ")),
               len(lines))
    return lines[start + 1:end]


def _stream(section: list[str]) -> list[tuple[int, int, int]]:
    out = []
    for ln in section:
        if ln.startswith("DT-EV "):
            t, c, v = ln.split()[1:4]
            out.append((int(t), int(c), int(v)))
    return out


@pytest.fixture(scope="module")
def vm_run(assets, calibrated_events):
    events, cal = calibrated_events
    bindir = Path(sys.executable).parent
    play = [str(bindir / "depthtouch"), "play", str(events), "--uinput", "--calibration",
            str(cal), "--uinput-settle", "2", "-q"]
    py = shlex.quote(sys.executable)
    script = events.with_name("guest.sh")
    script.write_text(
        "export PYTHONDONTWRITEBYTECODE=1\ncd /\n"
        'echo "DT-VM: run full"\n'
        f"{py} {GUEST} -- {shlex.join(play)}\n"
        'echo "DT-VM: run sigterm"\n'
        f"{py} {GUEST} --sigterm-after {SIGTERM_AFTER_REPORTS} -- {shlex.join(play)}\n"
        'echo "DT-VM: end"\n'
    )
    result = boot(assets, script, timeout_s=600)
    text = "\n".join(result.lines[-40:])
    assert not result.timed_out, f"the VM did not power off in time:\n{text}"
    assert "DT-VM: end" in result.lines, f"the guest script did not finish:\n{text}"
    errors = [ln for ln in result.lines if ln.startswith(("DT-ERR", "DT-VM: insmod", "Traceback"))]
    assert not errors, "\n".join(errors)
    return result, expected_touches(events)


def test_kernel_delivers_the_events_file(vm_run):
    result, expected = vm_run
    want, dropped = expected.positions, expected.dropped
    section = _section(result.lines, "full")
    assert "DT-RC 0" in section
    dev = next(ln for ln in section if ln.startswith("DT-DEV"))
    assert "props=[1]" in dev and "bus=6" in dev  # INPUT_PROP_DIRECT, BUS_VIRTUAL
    contacts, touch = contacts_from_kernel(_stream(section))
    assert len(want) + dropped >= 5
    assert len(contacts) == len(want), "one tracking id per down"
    assert len({c.tracking_id for c in contacts}) == len(contacts)
    assert all(c.released for c in contacts), "every contact released"
    assert touch == 0
    released = sorted(zip(contacts, want), key=lambda cw: cw[0].release_rank)
    assert [tid for _, tid in released] == expected.ups, "released in the order of the ups"
    errs = [compare(c, w) for c, w in zip(contacts, want.values())]
    for c, w in zip(contacts, want.values()):
        assert c.positions == rounded(w), f"tracking id {c.tracking_id}: positions differ"
    print(f"uinput VM: {len(contacts)} contacts ({dropped} more than the slots dropped), "
          f"max position error {max(errs):.3f} screen px, "
          f"VM wall {result.seconds:.1f} s")
    assert max(errs) <= 1.0


def test_sigterm_mid_touch_releases_every_contact(vm_run):
    result, expected = vm_run
    want = expected.positions
    section = _section(result.lines, "sigterm")
    assert "DT-KILL" in section and "DT-RC 0" in section
    kill = section.index("DT-KILL")
    before, _ = contacts_from_kernel(_stream(section[:kill]))
    contacts, touch = contacts_from_kernel(_stream(section))
    assert any(not c.released for c in before), "the kill came while a contact was down"
    assert 1 <= len(contacts) < len(want)
    assert all(c.released for c in contacts) and touch == 0, "nothing left down"
    for c, w in zip(contacts, want.values()):
        assert c.positions == rounded(w)[:len(c.positions)], "a prefix of the touch's positions"
        assert compare(c, w) <= 1.0
