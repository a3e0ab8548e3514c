"""The multi-camera evaluation: one simulated scene seen by several cameras, each camera alone
and all of them fused, scored on the shared screen (``eval --space screen``).

::

    scores = score_views("occlude", default_poses(2), camera="kinect-v1", seed=1)
    print(scores.row())  # recall, error, id switches: camera 0 / camera 1 / fused

Each camera runs its own pipeline (calibrated to the screen by its exact homography); the fused
run is :class:`~depthtouch.multicam.MultiPipeline` over the merged streams, through the one loop
(:func:`~depthtouch.driver.drive`). Truth is the reference camera's (noise-free) truth.
"""

from __future__ import annotations

import collections
from collections.abc import Sequence
from dataclasses import dataclass

from ..calibration import Calibration
from ..driver import drive
from ..fusion import FusionConfig, in_screen
from ..multicam import MultiPipeline, merge_by_time
from ..pipeline import Pipeline
from ..sim.multiview import MultiViewRecording, ViewPose, render_views
from ..sources.base import ArraySource
from ..types import TouchEvent
from .metrics import evaluate, truth_from_dict
from .suiterun import EventCollector
from .summary import Metrics, summarize


@dataclass(frozen=True)
class ViewScores:
    """One scene's scores: ``singles[k]`` camera k alone, ``fused`` all cameras fused; the fused
    events (with ``cam``, ``sx``, ``sy``) for further checks."""

    scene: str
    singles: list[Metrics]
    fused: Metrics
    fused_events: list[TouchEvent]

    def cams_per_id(self) -> dict[int, set[int]]:
        """Fused id -> the cameras that were its best camera at some time."""
        cams: dict[int, set[int]] = collections.defaultdict(set)
        for e in self.fused_events:
            cams[e.id].add(int(e.extra["cam"]))
        return dict(cams)

    def row(self) -> str:
        """A markdown table row: contact recall, frame recall, false touches, id switches,
        median error (mm), each as camera 0 / camera 1 / ... / fused."""
        runs = [*self.singles, self.fused]

        def col(fmt: str, get: object) -> str:
            return " / ".join(fmt.format(get(m)) for m in runs)  # type: ignore[operator]

        return (f"| {self.scene} | {col('{:.2f}', lambda m: m.contact_recall)} | "
                f"{col('{:.2f}', lambda m: m.frame_recall)} | "
                f"{col('{}', lambda m: m.false_touches)} | {col('{}', lambda m: m.id_switches)} | "
                f"{col('{:.2f}', lambda m: m.error_median_mm)} |")


def view_source(mv: MultiViewRecording, k: int) -> ArraySource:
    """View ``k``'s frames as a source."""
    v = mv.views[k]
    return ArraySource(v.depth, mv.timestamps_s, 0.001, v.K, name=f"view{k}")


def view_pipeline(mv: MultiViewRecording, k: int) -> Pipeline:
    """A pipeline for view ``k``, calibrated to the shared screen by its exact homography."""
    v = mv.views[k]
    return Pipeline(calibration=Calibration(v.H_to_screen, mv.screen_wh, 0.0), strict=True)


def score_recording(mv: MultiViewRecording, fusion: FusionConfig | None = None) -> ViewScores:
    """Score every view alone and the views fused against the screen truth."""
    truth = truth_from_dict(mv.reference.truth)

    def score(events: list[TouchEvent]) -> Metrics:
        return summarize([evaluate(truth, in_screen(events))])

    singles = []
    for k in range(len(mv.views)):
        collect = EventCollector()
        drive(view_source(mv, k), view_pipeline(mv, k), [collect])
        singles.append(score(collect.events))
    fused = EventCollector()
    multi = MultiPipeline([view_pipeline(mv, k) for k in range(len(mv.views))], fusion)
    drive(merge_by_time([view_source(mv, k) for k in range(len(mv.views))]), multi, [fused])
    return ViewScores(str(mv.reference.truth["scene"]), singles, score(fused.events),
                      fused.events)


def score_views(scene: str, poses: Sequence[ViewPose], *, camera: str = "kinect-v1",
                seed: int = 1, fusion: FusionConfig | None = None) -> ViewScores:
    """Render ``scene`` from ``poses`` (:func:`~depthtouch.sim.multiview.render_views`) and
    score it (:func:`score_recording`)."""
    return score_recording(render_views(scene, list(poses), camera=camera, seed=seed), fusion)
