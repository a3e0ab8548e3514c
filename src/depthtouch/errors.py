"""Error types: one per layer, each carrying a one-line message that names the problem and the fix.

The CLI turns any :class:`DepthTouchError` into that one line and exit code 2; anything else is a
bug and keeps its traceback.
"""

from __future__ import annotations


class DepthTouchError(Exception):
    """Base of every error the project raises on purpose (bad input, bad config, missing device)."""


class ConfigError(DepthTouchError, ValueError):
    """A configuration value or file is invalid; the message names the allowed range."""


class SourceError(DepthTouchError):
    """A depth source cannot be opened or read (missing file, wrong format, unplugged camera)."""


class SurfaceError(DepthTouchError):
    """The surface model cannot be learned, loaded or used with this stream."""


class CalibrationError(DepthTouchError):
    """A calibration cannot be fitted, loaded or applied."""


class OutputError(DepthTouchError):
    """An output (events file, TUIO socket, web server) cannot be opened."""
