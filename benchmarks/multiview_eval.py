"""The multi-camera evaluation table of docs/multicam.md: simulated scenes seen by two cameras
at different poses, each camera alone and fused, scored on the shared screen.

Rows: contact recall, frame recall, false touches, id switches and median error (mm), each as
camera 0 / camera 1 / fused (``depthtouch.evaluation.multiview``). Pose sets: ``side`` (two
Kinect v1 profiles 0.8 m apart at 1 m, side by side), ``rot90-rot180`` (the left one turned
90 deg about its optical axis, the right one upside down) and ``rot180-yaw12`` (the left one
upside down, the right one yawed 12 deg toward the middle).

Usage: python benchmarks/multiview_eval.py [--seed 1] [--poses side] [scene ...]
"""

from __future__ import annotations

import argparse
import time

from depthtouch.evaluation.multiview import score_views
from depthtouch.sim.multiview import ViewPose, default_poses

POSES = {
    "side": default_poses(2),
    "rot90-rot180": [ViewPose((-400.0, 0.0, 0.0), (0.0, 0.0, 90.0)),
                     ViewPose((400.0, 0.0, 0.0), (0.0, 0.0, 180.0))],
    "rot180-yaw12": [ViewPose((-400.0, 0.0, 0.0), (0.0, 0.0, 180.0)),
                     ViewPose((400.0, 0.0, 0.0), (0.0, 12.0, 0.0))],
}
SCENES = ("drags", "taps", "multitouch", "cross", "occlude")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenes", nargs="*", default=list(SCENES))
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--poses", choices=sorted(POSES), default="side")
    ap.add_argument("--camera", default="kinect-v1")
    a = ap.parse_args()
    print(f"poses {a.poses}, camera {a.camera}, seed {a.seed}")
    print("| scene | contact recall | frame recall | false | id switches | median error (mm) |")
    print("|---|---|---|---|---|---|")
    for scene in a.scenes:
        t0 = time.perf_counter()
        s = score_views(scene, POSES[a.poses], camera=a.camera, seed=a.seed)
        print(s.row(), f"<!-- {time.perf_counter() - t0:.1f} s -->", flush=True)


if __name__ == "__main__":
    main()
