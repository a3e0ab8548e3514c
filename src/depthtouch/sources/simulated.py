"""The simulator as a depth source: ``open_source("sim:drags")`` renders a scene and plays it.

The scene is rendered once when the source opens (a few seconds of frames), then yielded frame
by frame like a recording. The ground truth is available as :attr:`SimSource.truth`.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

from ..errors import ConfigError, SourceError
from ..types import Frame
from .base import SourceBase

_OPTIONS = ("camera", "distance_m", "tilt_deg", "surface", "seed", "fps", "noise")


class SimSource(SourceBase):
    """Frames of a simulated scene (see :func:`depthtouch.sim.render_scene` for the options)."""

    def __init__(self, scene: str, **options: Any) -> None:
        from ..sim import HARD_SCENES, SCENES, render_scene

        if scene not in SCENES + HARD_SCENES:
            raise SourceError(f"unknown simulator scene {scene!r}; use sim:NAME with NAME one of "
                              f"{', '.join(SCENES + HARD_SCENES)}")
        unknown = sorted(set(options) - set(_OPTIONS))
        if unknown:
            raise SourceError(f"sim:{scene}: unknown option(s) {', '.join(unknown)}; "
                              f"allowed {', '.join(_OPTIONS)}")
        try:
            self.recording = render_scene(scene, **options)
        except ConfigError as e:
            raise SourceError(f"sim:{scene}: {e}") from e
        rec = self.recording
        self.name = f"sim:{scene}"
        self.depth_scale_m = rec.depth_scale_m
        self.K = rec.K
        self.fps = rec.fps
        self.resolution_wh = (int(rec.depth.shape[2]), int(rec.depth.shape[1]))
        self.truth = rec.truth

    def __len__(self) -> int:
        return int(self.recording.depth.shape[0])

    def frames(self) -> Iterator[Frame]:
        rec = self.recording
        for i in range(rec.depth.shape[0]):
            yield Frame(rec.depth[i], float(rec.timestamps_s[i]), i, rec.depth_scale_m, rec.K)


def open_sim_source(scene: str, **options: Any) -> SimSource:
    """A :class:`SimSource` for ``scene``; options are render_scene's keywords.

    Unknown scenes or options raise SourceError listing the valid ones.
    """
    return SimSource(scene, **options)
