"""A virtual direct-touch screen on Linux through ``/dev/uinput`` (multi-touch protocol B).

Two layers:

- :class:`TouchEncoder`: pure state machine, touch events in -> the exact evdev events out, as
  ``(type, code, value)`` triples. Each ``down`` takes the lowest free slot and a new tracking id,
  a ``move`` writes only the values that changed, an ``up`` writes its last position then releases
  the slot (``ABS_MT_TRACKING_ID -1``). ``ABS_X``/``ABS_Y`` follow the oldest live contact and
  ``BTN_TOUCH`` says whether any contact is down: the kernel does not emulate them for uinput
  devices. One ``SYN_REPORT`` closes every frame that wrote something.
- :class:`UinputSink`: the thin sink that creates the device with python-evdev
  (``INPUT_PROP_DIRECT``, ``BUS_VIRTUAL``, 10 slots by default) and writes the encoder's events.
  ``close()`` releases every contact, so no finger stays down on the desktop.

Positions are screen pixels: the events' ``sx``, ``sy`` (from a calibration), or the calibration's
homography when an event has none, or the depth-image pixels ``x``, ``y`` without a calibration.
The axes' ranges are the screen size (``[0, w - 1]`` x ``[0, h - 1]``); positions are rounded and
clipped into them. See docs/uinput.md for permissions and mapping the device to a monitor.
"""

from __future__ import annotations

import logging
import math
import os
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from ..errors import ConfigError, OutputError
from ..types import FrameResult, TouchEvent
from .base import SinkBase

log = logging.getLogger(__name__)

# linux/input-event-codes.h and linux/input.h (stable kernel ABI); kept here so that the pure
# encoder needs no python-evdev.
EV_SYN, EV_KEY, EV_ABS = 0x00, 0x01, 0x03
SYN_REPORT = 0
BTN_TOUCH = 0x14A
ABS_X, ABS_Y = 0x00, 0x01
ABS_MT_SLOT = 0x2F
ABS_MT_TOUCH_MAJOR = 0x30
ABS_MT_POSITION_X, ABS_MT_POSITION_Y = 0x35, 0x36
ABS_MT_TRACKING_ID = 0x39
INPUT_PROP_DIRECT = 0x01
BUS_VIRTUAL = 0x06

UINPUT_PATH = "/dev/uinput"
TRACKING_ID_MAX = 65535
DEVICE_NAME = "depthtouch virtual touchscreen"

InputEvent = tuple[int, int, int]
"""One evdev event: ``(type, code, value)``."""

_FIX = ("load the module with `sudo modprobe uinput` and give your user access with the udev rule "
        "in docs/uinput.md (KERNEL==\"uinput\", GROUP=\"input\", MODE=\"0660\")")


@dataclass(frozen=True)
class UinputConfig:
    """The virtual touchscreen's shape.

    screen_wh_px: axis ranges in pixels (width, height), each in [1, 65535]: the calibration's
        screen, or the depth image without one.
    slots: simultaneous contacts, [10, 64] (default 10); a down beyond them is dropped (counted).
    touch_major: also report ``ABS_MT_TOUCH_MAJOR`` from the events' ``area`` (the diameter of a
        disc of that many depth pixels, in depth pixels; default False).
    settle_s: wait after creating the device so that the desktop opens it before the first touch,
        and before destroying it so that the desktop reads the last releases, seconds in [0, 10]
        (default 0.5; the kernel delivers nothing before a reader opens the device and drops
        what is unread when it goes).
    name: the device name shown by evtest and libinput.
    """

    screen_wh_px: tuple[int, int]
    slots: int = 10
    touch_major: bool = False
    settle_s: float = 0.5
    name: str = DEVICE_NAME

    def __post_init__(self) -> None:
        wh = self.screen_wh_px
        if (len(wh) != 2 or any(isinstance(v, bool) or not isinstance(v, int) for v in wh)
                or not all(1 <= v <= 65535 for v in wh)):
            raise ConfigError(
                f"uinput screen size {wh!r} is not two whole numbers in [1, 65535]; "
                "e.g. (1920, 1080)"
            )
        if isinstance(self.slots, bool) or not 10 <= self.slots <= 64:
            raise ConfigError(f"uinput slots = {self.slots!r} is out of range; allowed [10, 64]")
        if not 0.0 <= self.settle_s <= 10.0:
            raise ConfigError(f"uinput settle_s = {self.settle_s!r} is out of range; [0, 10]")
        if not self.name or len(self.name.encode()) >= 80:  # UINPUT_MAX_NAME_SIZE
            raise ConfigError("uinput device name must be 1 to 79 bytes long")


def screen_xy(event: TouchEvent, calibration: Any | None) -> tuple[float, float]:
    """The event's position in screen pixels (``sx``, ``sy``; else mapped; else ``x``, ``y``)."""
    sx, sy = event.extra.get("sx"), event.extra.get("sy")
    if isinstance(sx, (int, float)) and isinstance(sy, (int, float)):
        return float(sx), float(sy)
    if calibration is not None:
        x, y = calibration.to_screen((event.x, event.y))
        return float(x), float(y)
    return event.x, event.y


def _axis(value: float, size: int) -> int:
    if not math.isfinite(value):
        return (size - 1) // 2
    return min(max(int(math.floor(value + 0.5)), 0), size - 1)


@dataclass
class _Contact:
    slot: int
    tracking_id: int
    x: int
    y: int
    major: int | None


class TouchEncoder:
    """Touch events -> evdev events for one device; ``update()`` per frame, ``reset()``.

    calibration: optional, maps events without ``sx``, ``sy`` to the screen (anything with
    ``to_screen``); without it such events use their depth-image ``x``, ``y``.
    """

    def __init__(self, config: UinputConfig, calibration: Any | None = None) -> None:
        self.config = config
        self.calibration = calibration
        self.dropped = 0
        self.reset()

    def reset(self) -> None:
        """Forget every contact without writing anything (the device is new or gone)."""
        self._contacts: dict[int, _Contact] = {}  # by touch id, in order of their down
        self._slot = 0  # the kernel's current slot starts at 0
        self._next_tracking_id = 0
        self._pointer_x: int | None = None
        self._pointer_y: int | None = None
        self._touching = False

    @property
    def active(self) -> int:
        """Contacts down now."""
        return len(self._contacts)

    def _select(self, slot: int, out: list[InputEvent]) -> None:
        if slot != self._slot:
            out.append((EV_ABS, ABS_MT_SLOT, slot))
            self._slot = slot

    def _major(self, event: TouchEvent) -> int | None:
        if not self.config.touch_major:
            return None
        area = event.extra.get("area")
        if not isinstance(area, (int, float)) or not math.isfinite(area) or area <= 0:
            return 0
        return int(round(2.0 * math.sqrt(float(area) / math.pi)))

    def _down(self, e: TouchEvent, out: list[InputEvent]) -> None:
        used = {c.slot for c in self._contacts.values()}
        free = [s for s in range(self.config.slots) if s not in used]
        if not free:
            self.dropped += 1
            if self.dropped == 1:
                log.warning("uinput: more than %d contacts; dropping the extra ones (warned once)",
                            self.config.slots)
            return
        w, h = self.config.screen_wh_px
        sx, sy = screen_xy(e, self.calibration)
        c = _Contact(free[0], self._next_tracking_id, _axis(sx, w), _axis(sy, h), self._major(e))
        self._next_tracking_id = (self._next_tracking_id + 1) % (TRACKING_ID_MAX + 1)
        self._contacts[e.id] = c
        self._select(c.slot, out)
        out += [(EV_ABS, ABS_MT_TRACKING_ID, c.tracking_id),
                (EV_ABS, ABS_MT_POSITION_X, c.x), (EV_ABS, ABS_MT_POSITION_Y, c.y)]
        if c.major is not None:
            out.append((EV_ABS, ABS_MT_TOUCH_MAJOR, c.major))

    def _move(self, c: _Contact, e: TouchEvent, out: list[InputEvent]) -> None:
        w, h = self.config.screen_wh_px
        sx, sy = screen_xy(e, self.calibration)
        x, y, major = _axis(sx, w), _axis(sy, h), self._major(e)
        changed: list[InputEvent] = []
        if x != c.x:
            changed.append((EV_ABS, ABS_MT_POSITION_X, x))
        if y != c.y:
            changed.append((EV_ABS, ABS_MT_POSITION_Y, y))
        if major is not None and major != c.major:
            changed.append((EV_ABS, ABS_MT_TOUCH_MAJOR, major))
        if changed:
            self._select(c.slot, out)
            out += changed
            c.x, c.y, c.major = x, y, major

    def update(self, events: Sequence[TouchEvent]) -> list[InputEvent]:
        """One frame's touch events -> its evdev events, ending with ``SYN_REPORT``; ``[]`` when
        nothing changed. An event for an unknown id that is not a ``down`` is ignored (its down
        was dropped for lack of slots); a repeated ``down`` restarts the contact."""
        out: list[InputEvent] = []
        for e in events:
            c = self._contacts.get(e.id)
            if e.state == "down":
                if c is not None:
                    self._release(e.id, out)
                self._down(e, out)
            elif c is not None:
                self._move(c, e, out)
                if e.state == "up":
                    self._release(e.id, out)
        return self._finish(out)

    def _release(self, touch_id: int, out: list[InputEvent]) -> None:
        c = self._contacts.pop(touch_id)
        self._select(c.slot, out)
        out.append((EV_ABS, ABS_MT_TRACKING_ID, -1))

    def release_all(self) -> list[InputEvent]:
        """The events that lift every contact still down (``[]`` when none is)."""
        out: list[InputEvent] = []
        for touch_id in list(self._contacts):
            self._release(touch_id, out)
        return self._finish(out)

    def _finish(self, out: list[InputEvent]) -> list[InputEvent]:
        if self._contacts:  # the single-touch pointer follows the oldest contact
            oldest = next(iter(self._contacts.values()))
            if oldest.x != self._pointer_x:
                out.append((EV_ABS, ABS_X, oldest.x))
            if oldest.y != self._pointer_y:
                out.append((EV_ABS, ABS_Y, oldest.y))
            self._pointer_x, self._pointer_y = oldest.x, oldest.y
        touching = bool(self._contacts)
        if touching != self._touching:
            out.append((EV_KEY, BTN_TOUCH, int(touching)))
            self._touching = touching
        if out:
            out.append((EV_SYN, SYN_REPORT, 0))
        return out


def check_uinput_access(path: str | None = None) -> None:
    """OutputError naming the fix when ``path`` (default /dev/uinput) is missing or not writable
    by this user."""
    path = path or UINPUT_PATH
    if not os.path.exists(path):
        raise OutputError(f"{path} does not exist; {_FIX}")
    if not os.access(path, os.R_OK | os.W_OK):
        raise OutputError(f"{path} is not writable by this user; {_FIX}")


def _import_evdev() -> Any:
    try:
        import evdev
    except ImportError as e:
        raise OutputError(
            f"--uinput needs python-evdev ({e}); pip install 'depthtouch[uinput]'"
        ) from e
    return evdev


class UinputSink(SinkBase):
    """Writes touch events to a new virtual touchscreen.

    screen_wh_px: the axes' ranges; None takes the calibration's screen, else the first frame's
        depth-image size (the device is then created at the first frame).
    calibration: maps events without ``sx``, ``sy``; see :class:`TouchEncoder`.
    slots, touch_major, settle_s: see :class:`UinputConfig`. path: the uinput node (default
    /dev/uinput).

    Raises OutputError (one line naming the fix) when ``path`` is missing or not writable, or
    python-evdev is not installed. Write errors are counted in ``errors`` and logged once.
    """

    def __init__(
        self,
        screen_wh_px: tuple[int, int] | None = None,
        *,
        calibration: Any | None = None,
        slots: int = 10,
        touch_major: bool = False,
        settle_s: float = 0.5,
        path: str | None = None,
    ) -> None:
        if screen_wh_px is None and calibration is not None:
            screen_wh_px = tuple(calibration.screen_wh)
        self._slots, self._touch_major, self._settle_s = slots, touch_major, settle_s
        self.calibration = calibration
        self.path = path = path or UINPUT_PATH
        self.encoder: TouchEncoder | None = None
        if screen_wh_px is not None:  # validate before touching the device
            self.encoder = TouchEncoder(self._config(screen_wh_px), calibration)
        check_uinput_access(path)
        self._evdev = _import_evdev()
        self._device: Any | None = None
        self.errors = 0
        self.events_written = 0
        self._closed = False
        if self.encoder is not None:
            self._open(self.encoder.config)

    def _config(self, screen_wh_px: tuple[int, int]) -> UinputConfig:
        return UinputConfig(screen_wh_px, slots=self._slots, touch_major=self._touch_major,
                            settle_s=self._settle_s)

    def _open(self, cfg: UinputConfig) -> None:
        ecodes, AbsInfo = self._evdev.ecodes, self._evdev.AbsInfo  # noqa: N806
        w, h = cfg.screen_wh_px

        def axis(size: int) -> Any:
            return AbsInfo(value=0, min=0, max=size - 1, fuzz=0, flat=0, resolution=0)

        abs_axes = [
            (ABS_X, axis(w)), (ABS_Y, axis(h)),
            (ABS_MT_SLOT, AbsInfo(0, 0, cfg.slots - 1, 0, 0, 0)),
            (ABS_MT_TRACKING_ID, AbsInfo(0, 0, TRACKING_ID_MAX, 0, 0, 0)),
            (ABS_MT_POSITION_X, axis(w)), (ABS_MT_POSITION_Y, axis(h)),
        ]
        if cfg.touch_major:
            abs_axes.append((ABS_MT_TOUCH_MAJOR, AbsInfo(0, 0, max(w, h), 0, 0, 0)))
        caps = {ecodes.EV_KEY: [BTN_TOUCH], ecodes.EV_ABS: abs_axes}
        try:
            self._device = self._evdev.UInput(
                caps, name=cfg.name, bustype=BUS_VIRTUAL, vendor=0, product=0, version=1,
                devnode=self.path, input_props=[INPUT_PROP_DIRECT],
            )
        except (OSError, self._evdev.UInputError) as e:
            raise OutputError(f"cannot create the virtual touchscreen on {self.path} ({e}); "
                              f"{_FIX}") from e
        if cfg.settle_s > 0:
            time.sleep(cfg.settle_s)

    def send(self, result: FrameResult) -> None:
        if self._closed:
            return
        frame, events = result.frame, result.events
        if self.encoder is None:
            w, h = frame.resolution_wh
            self.encoder = TouchEncoder(self._config((w, h)), self.calibration)
            self._open(self.encoder.config)
        self._write(self.encoder.update(events))

    def _write(self, stream: list[InputEvent]) -> None:
        dev = self._device
        if dev is None or not stream:
            return
        try:
            for type_, code, value in stream:
                dev.write(type_, code, value)
            self.events_written += len(stream)
        except OSError as e:
            self.errors += 1
            if self.errors == 1:
                log.warning("uinput output: write failed (%s); carrying on (warned once)", e)

    def close(self) -> None:
        """Lift every contact still down, then destroy the device; safe to call twice."""
        if self._closed:
            return
        self._closed = True
        if self.encoder is not None:
            self._write(self.encoder.release_all())
        dev, self._device = self._device, None
        if dev is None:
            return
        try:
            # the kernel drops a reader's unread events when the device goes: give the desktop
            # the time to read the last releases
            if self.events_written and self._settle_s > 0:
                time.sleep(self._settle_s)
        finally:
            dev.close()
