"""depthtouch: turn any surface into a multi-touch screen with one depth camera.

The per-frame data flow is source -> surface -> regions -> touch points -> tracking -> filters ->
calibration -> outputs; :class:`Pipeline` wires the stages, :func:`drive` is the one loop::

    from depthtouch import Pipeline, PipelineConfig, open_source

    with open_source("sim:taps") as source:
        pipeline = Pipeline(PipelineConfig())
        for frame in source.frames():
            for event in pipeline.process(frame).events:
                print(event.id, event.state, event.x, event.y)

The names below are imported when first used, so ``import depthtouch`` stays cheap (the touch
kernels are compiled or loaded only when a :class:`Pipeline` is made).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

__version__ = "0.1.0"

__all__ = [
    "DepthTouchError",
    "Frame",
    "FrameResult",
    "Pipeline",
    "PipelineConfig",
    "TouchEvent",
    "__version__",
    "drive",
    "load_config",
    "open_outputs",
    "open_source",
]

_WHERE = {
    "Pipeline": "pipeline",
    "PipelineConfig": "config",
    "load_config": "config",
    "drive": "driver",
    "open_source": "sources",
    "open_outputs": "outputs",
    "Frame": "types",
    "FrameResult": "types",
    "TouchEvent": "types",
    "DepthTouchError": "errors",
}

if TYPE_CHECKING:
    from .config import PipelineConfig, load_config
    from .driver import drive
    from .errors import DepthTouchError
    from .outputs import open_outputs
    from .pipeline import Pipeline
    from .sources import open_source
    from .types import Frame, FrameResult, TouchEvent


def __getattr__(name: str) -> Any:
    where = _WHERE.get(name)
    if where is None:
        raise AttributeError(f"module 'depthtouch' has no attribute {name!r}")
    import importlib

    return getattr(importlib.import_module(f".{where}", __name__), name)
