"""depthtouch: turn any surface into a multi-touch screen with one depth camera.

The per-frame data flow is source -> surface -> regions -> touch points -> tracking -> filters ->
calibration -> outputs; :class:`depthtouch.pipeline.Pipeline` wires the stages together.
"""

from __future__ import annotations

__version__ = "0.1.0"

__all__ = ["__version__"]
