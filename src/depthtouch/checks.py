"""Checks written once: a number in its range, a HOST:PORT address.

Every setting and option is checked here, so that every message reads the same way: the name,
the value, the allowed range or form and an example, on one line.
"""

from __future__ import annotations

from .errors import ConfigError, DepthTouchError


def show(value: object, limit: int = 30) -> str:
    """repr for a one-line message, shortened (a TOML integer may have hundreds of digits)."""
    r = " ".join(repr(value).split())
    return r if len(r) <= limit else r[: limit - 3] + "..."


def check_range(name: str, value: float, lo: float, hi: float, *, lo_open: bool = False,
                hi_open: bool = False, error: type[DepthTouchError] = ConfigError) -> None:
    """Raise ``error`` unless lo <= value <= hi (strict on an open side); NaN is never in range.

    The message is ``"NAME = VALUE is out of range; allowed [lo, hi]"``."""
    bad_lo = value <= lo if lo_open else value < lo
    bad_hi = value >= hi if hi_open else value > hi
    if bad_lo or bad_hi or value != value:
        lb, rb = "(" if lo_open else "[", ")" if hi_open else "]"
        raise error(f"{name} = {show(value)} is out of range; allowed {lb}{lo}, {hi}{rb}")


def parse_address(text: str, *, what: str, default_port: int, default_host: str | None = None,
                  allow_port_zero: bool = False) -> tuple[str, int]:
    """``"HOST:PORT"`` (``"[::1]:PORT"`` for IPv6), ``"HOST"`` (the default port), and, when a
    ``default_host`` is given, ``":PORT"`` or ``"PORT"`` -> ``(host, port)``.

    what: names the option in the message (e.g. "TUIO address"). Port 0 (any free port) only
    with ``allow_port_zero``. ConfigError (one line) when malformed.
    """
    s = str(text).strip()
    lo = 0 if allow_port_zero else 1
    host, port_text = "", ""
    if s.startswith("["):
        end = s.find("]")
        if end > 0:
            host, rest = s[1:end], s[end + 1:]
            port_text = rest[1:] if rest.startswith(":") else ("" if rest else str(default_port))
    elif s.count(":") == 1:
        host, port_text = s.split(":")
    elif ":" not in s:
        if default_host is not None and s.isdigit():
            host, port_text = "", s
        else:
            host, port_text = s, str(default_port)
    if not host and default_host is not None and port_text:
        host = default_host
    if not host or not port_text.isdigit() or not lo <= int(port_text) <= 65535:
        example = f"127.0.0.1:{default_port}"
        raise ConfigError(f"{what} {text!r} is not HOST:PORT with a port in [{lo}, 65535]; "
                          f"e.g. {example}")
    return host, int(port_text)
