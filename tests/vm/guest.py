"""Runs inside the emulated machine: start ``depthtouch play ... --uinput``, read what the kernel
delivers on the new ``/dev/input/eventN`` and print it on the serial console.

Usage: guest.py [--sigterm-after N] -- PLAY-COMMAND...

Prints ``DT-EV type code value`` per event, ``DT-KILL`` when it sends SIGTERM (after N reports
with a contact down), ``DT-RC rc`` with play's exit code, ``DT-ERR ...`` on a failure, and
``DT-DONE`` last. Only python-evdev and the standard library are imported here.
"""

from __future__ import annotations

import os
import select
import signal
import subprocess
import sys
import time

import evdev

NAME = "depthtouch virtual touchscreen"
EV_SYN, EV_ABS, SYN_REPORT, SYN_DROPPED = 0, 3, 0, 3
ABS_MT_SLOT, ABS_MT_TRACKING_ID = 0x2F, 0x39


def say(text: str) -> None:
    sys.stdout.write(text + "\n")
    sys.stdout.flush()


def find_device(proc: subprocess.Popen, timeout_s: float = 120.0) -> evdev.InputDevice | None:
    seen: set[str] = set()
    t_end = time.monotonic() + timeout_s
    while time.monotonic() < t_end and proc.poll() is None:
        for path in sorted(os.listdir("/dev/input")):
            full = f"/dev/input/{path}"
            if not path.startswith("event") or full in seen:
                continue
            seen.add(full)
            try:
                dev = evdev.InputDevice(full)
            except OSError:
                seen.discard(full)  # not ready yet
                continue
            if dev.name == NAME:
                return dev
            dev.close()
        time.sleep(0.005)
    return None


def main(argv: list[str]) -> int:
    sep = argv.index("--")
    opts, cmd = argv[:sep], argv[sep + 1:]
    kill_after = int(opts[opts.index("--sigterm-after") + 1]) if "--sigterm-after" in opts else 0
    proc = subprocess.Popen(cmd)
    dev = find_device(proc)
    if dev is None:
        say(f"DT-ERR no device named {NAME!r} appeared (play rc {proc.poll()})")
        proc.kill()
        say(f"DT-RC {proc.wait()}")
        return 1
    say(f"DT-DEV {dev.path} props={dev.input_props()} bus={dev.info.bustype}")
    slot, ids = 0, {}  # the kernel's current slot and each slot's tracking id
    reports_down, killed = 0, False
    while True:
        ready, _, _ = select.select([dev.fd], [], [], 1.0)
        if not ready:
            if proc.poll() is not None:
                say("DT-ERR play ended but its device is still there")
                break
            continue
        try:
            events = list(dev.read())
        except BlockingIOError:
            continue
        except OSError:  # ENODEV: play closed the device
            break
        for e in events:
            say(f"DT-EV {e.type} {e.code} {e.value}")
            if e.type == EV_ABS and e.code == ABS_MT_SLOT:
                slot = e.value
            elif e.type == EV_ABS and e.code == ABS_MT_TRACKING_ID:
                ids[slot] = e.value
            elif e.type == EV_SYN and e.code == SYN_DROPPED:
                say("DT-ERR the reader fell behind (SYN_DROPPED)")
            elif e.type == EV_SYN and e.code == SYN_REPORT and any(v >= 0 for v in ids.values()):
                reports_down += 1
                if kill_after and not killed and reports_down >= kill_after:
                    proc.send_signal(signal.SIGTERM)
                    killed = True
                    say("DT-KILL")
    try:
        rc = proc.wait(timeout=120)
    except subprocess.TimeoutExpired:
        proc.kill()
        rc = proc.wait()
        say("DT-ERR play did not end")
    say(f"DT-RC {rc}")
    return 0


if __name__ == "__main__":
    code = main(sys.argv[1:])
    say("DT-DONE")
    sys.exit(code)
