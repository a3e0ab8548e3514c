"""The simulator as a depth source: ``open_source("sim:drags")`` renders a scene and plays it.

The scene is rendered once when the source opens (a few seconds of frames), then yielded frame
by frame like a recording. The ground truth is available as :attr:`SimSource.truth`.
"""

from __future__ import annotations

from typing import Any

from ..errors import ConfigError, SourceError
from .base import ArraySource

_OPTIONS = ("camera", "distance_m", "tilt_deg", "surface", "seed", "fps", "noise", "hand")


class SimSource(ArraySource):
    """Frames of a simulated scene (see :func:`depthtouch.sim.render_scene` for the options)."""

    def __init__(self, scene: str, **options: Any) -> None:
        from ..sim import ALL_SCENES, render_scene

        if scene not in ALL_SCENES:
            raise SourceError(f"unknown simulator scene {scene!r}; use sim:NAME with NAME one of "
                              f"{', '.join(ALL_SCENES)}")
        unknown = sorted(set(options) - set(_OPTIONS))
        if unknown:
            raise SourceError(f"sim:{scene}: unknown option(s) {', '.join(unknown)}; "
                              f"allowed {', '.join(_OPTIONS)}")
        try:
            self.recording = render_scene(scene, **options)
        except ConfigError as e:
            raise SourceError(f"sim:{scene}: {e}") from e
        rec = self.recording
        super().__init__(rec.depth, rec.timestamps_s, rec.depth_scale_m, rec.K, fps=rec.fps,
                         name=f"sim:{scene}")
        self.truth = rec.truth


def open_sim_source(scene: str, **options: Any) -> SimSource:
    """A :class:`SimSource` for ``scene``; options are render_scene's keywords.

    Unknown scenes or options raise SourceError listing the valid ones.
    """
    return SimSource(scene, **options)
