"""Boot time of the uinput test machine (QEMU, software emulation) and one short play inside it.

Each round boots Debian's kernel with the test initramfs (tests/vm/uinput_vm.py), runs
``depthtouch play --fast --uinput`` of a two-finger events file with the evdev reader
(tests/vm/guest.py), and powers off. Prints one markdown row per round and the medians: QEMU wall
time, the guest's uptime when /init reached the script (kernel + modules + 9p), and the guest time
of the play (Python start over 9p, imports, the device, 0.5 s settle twice).

Usage: python benchmarks/uinput_vm.py [--rounds 3]
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from vm.uinput_vm import MARK, boot, ensure_assets  # noqa: E402

GUEST = ROOT / "tests" / "vm" / "guest.py"


def _events(path: Path) -> Path:
    rows = []
    for k in range(30):
        state = "down" if k == 0 else ("up" if k == 29 else "move")
        for tid, y in ((1, 300.0), (2, 700.0)):
            rows.append({"frame": k, "t": k / 30, "id": tid, "state": state,
                         "x": 100.0 + 10 * k, "y": y})
    path.write_text("".join(json.dumps(r) + "\n" for r in rows))
    return path


def _uptime(lines: list[str], label: str) -> float | None:
    for ln in lines:
        if ln.startswith(f"{MARK} {label} "):
            return float(ln.split()[-1])
    return None


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--rounds", type=int, default=3)
    a = ap.parse_args(argv)
    assets = ensure_assets()
    with tempfile.TemporaryDirectory(prefix="uinput-bench-") as tmp:
        events = _events(Path(tmp) / "ev.jsonl")
        dt = Path(sys.executable).parent / "depthtouch"
        script = Path(tmp) / "guest.sh"
        script.write_text(
            "export PYTHONDONTWRITEBYTECODE=1\ncd /\n"
            f'echo "{MARK} play-start $(cut -d" " -f1 /proc/uptime)"\n'
            f"{sys.executable} {GUEST} -- {dt} play {events} --uinput --fast --screen 1920x1080"
            " -q | grep -c DT-EV\n"
            f'echo "{MARK} play-end $(cut -d" " -f1 /proc/uptime)"\n'
        )
        print(f"uinput VM, kernel {assets.release}, {platform.processor() or platform.machine()}"
              f", Python {platform.python_version()}\n")
        print("| round | QEMU wall s | boot to script s | play (guest) s | events read |")
        print("|---|---|---|---|---|")
        walls, boots, plays = [], [], []
        for k in range(a.rounds):
            r = boot(assets, script, timeout_s=300)
            start, end = _uptime(r.lines, "play-start"), _uptime(r.lines, "play-end")
            if r.timed_out or start is None or end is None or r.booted_s is None:
                print(f"| {k + 1} | failed | | | |\n" + "\n".join(r.lines[-20:]))
                return 1
            n = next((ln for ln in r.lines if ln.strip().isdigit()), "?")
            walls.append(r.seconds)
            boots.append(r.booted_s)
            plays.append(end - start)
            print(f"| {k + 1} | {r.seconds:.1f} | {r.booted_s:.1f} | {end - start:.1f} | {n} |",
                  flush=True)
        print(f"| median | {statistics.median(walls):.1f} | {statistics.median(boots):.1f} | "
              f"{statistics.median(plays):.1f} | |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
