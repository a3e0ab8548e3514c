"""How well one frame's touch point tells a contact from anything else: the tracker's evidence
rules against a classifier fitted on other suites (a study; docs/accuracy.md, session 46).

For every touch point of every frame of the given suite halves (default settings), its
features as the tracker sees them (region area in mm², tip height, attachment length and
height, the spread of the heights behind it, core height, Tl above its floor, the attachment's
share of the ring, the recent change around it, the distance to its hand) and its label from
the truth: *contact* when a visible contact lies within 12 mm, *other* when none lies within
20 mm (points between, or near a hidden contact, are left out); *hover >= 25 mm* marks the
others that lie within 20 mm of a fingertip hovering 25 mm or more up. The rules' score is the
evidence weight :func:`depthtouch.tracking.evidence.evidence` gives the point (the enclosure
test's refusals applied; 0 where the tip is too high to start a contact).

With scikit-learn installed (``pip install -e '.[study]'``), each suite is then scored by a
gradient-boosted classifier fitted on the others (leave one suite out): the area under the ROC
curve of both scores, and the share of contact points each passes when both pass the same
share of the other points (the rules' share of nonzero weights). Without it, the features are
written (``--out``) and the script says what is missing.

Run: ``.venv/bin/python benchmarks/evidence_study.py --suites hard,hard-extra,steep --half
tune [--workers 2] [--out points.npz]`` (recordings come from the suite cache, rendered when
missing).
"""

from __future__ import annotations

import argparse
import sys
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from depthtouch.evaluation.halves import select_half
from depthtouch.evaluation.suite import SuiteCase, ensure_recording, load_suite
from depthtouch.evaluation.suiterun import default_workers
from depthtouch.evaluation.truth import read_truth
from depthtouch.pipeline import Pipeline
from depthtouch.sources import open_source
from depthtouch.tracking.evidence import evidence, refused_out, steep_tips

FEATURES = ("area_mm2", "tip_mm", "attach_len_mm", "attach_height_mm", "back_spread_mm",
            "core_mm", "tl_above_floor_mm", "attach_share", "recent_change_mm", "hand_mm")
#: a point this near a visible contact is the contact's; one this far from every contact is not
CONTACT_MM, OTHER_MM = 12.0, 20.0
#: a point this near a fingertip hovering at least HOVER_MM up lies under that hover
HOVER_NEAR_MM, HOVER_MM = 20.0, 25.0


def _col(a: np.ndarray | None, n: int) -> np.ndarray:
    return np.full(n, np.nan) if a is None else np.asarray(a, np.float64)


def _nearest_mm(xy: np.ndarray, at: np.ndarray, scale: float) -> tuple[np.ndarray, np.ndarray]:
    """Distance (mm) from each point to the nearest of ``at`` and its index (inf, -1: none)."""
    if len(at) == 0:
        return np.full(len(xy), np.inf), np.full(len(xy), -1)
    d = np.hypot(xy[:, None, 0] - at[None, :, 0], xy[:, None, 1] - at[None, :, 1]) * scale
    k = d.argmin(axis=1)
    return d[np.arange(len(xy)), k], k


def case_points(case: SuiteCase) -> np.ndarray:
    """Rows (point, frame) of one case: the FEATURES, then the rules' weight and the label
    (1 contact, 0 other, -1 left out), then 1 where the point lies under a hover >= 25 mm."""
    rec, truth_path = ensure_recording(case)
    truth = read_truth(truth_path)
    pipe = Pipeline()
    cfg, on_mm = pipe.config.tracking, pipe.config.touchpoints.touch_on_mm
    rows = []
    with open_source(rec) as src:
        for frame in src:
            p = pipe.process(frame).points
            scale = pipe.surface.mm_per_px
            if p is None or not len(p) or pipe.surface.learning or not scale:
                continue
            n, xy = len(p), p.xy_px
            area = p.area_px.tolist()
            steep = steep_tips(p, area, scale, cfg)
            ok_new = [h <= on_mm or s for h, s in zip(p.height_mm.tolist(), steep, strict=True)]
            weight, refused = evidence(p, list(map(tuple, xy.tolist())), area, ok_new, steep,
                                       scale, cfg)
            w = np.array(refused_out(weight, refused)) * np.array(ok_new)
            c = truth.contact_frame == frame.index
            seen = ~truth.contact_occluded[c]
            d_seen, _ = _nearest_mm(xy, truth.contact_xy_px[c][seen], scale)
            d_hidden, _ = _nearest_mm(xy, truth.contact_xy_px[c][~seen], scale)
            label = np.where(d_seen < CONTACT_MM, 1, np.where(
                (d_seen >= OTHER_MM) & (d_hidden >= OTHER_MM), 0, -1))
            hv = truth.hover_frame == frame.index
            d_hover, k = _nearest_mm(xy, truth.hover_xy_px[hv], scale)
            high = np.zeros(n, bool)
            if hv.any():
                high = (d_hover < HOVER_NEAR_MM) & (truth.hover_height_mm[hv][k] >= HOVER_MM)
            hand = p.hand_xy_px
            rows.append(np.column_stack([
                p.area_px * scale * scale, p.height_mm,
                np.maximum(_col(p.attach_px, n) / 2.0 - 4.0, 0.0) * scale,
                _col(p.attach_height_mm, n), _col(p.back_spread_mm, n), _col(p.core_height_mm, n),
                _col(p.tl_above_floor_mm, n), _col(p.attach_share, n),
                _col(p.recent_change_mm, n),
                np.hypot(xy[:, 0] - hand[:, 0], xy[:, 1] - hand[:, 1]) * scale,
                w, label, high & (label == 0)]))
    return np.concatenate(rows) if rows else np.zeros((0, len(FEATURES) + 3))


def collect(suites: list[str], half: str, workers: int) -> dict[str, np.ndarray]:
    out = {}
    for name in suites:
        cases = select_half(load_suite(name).cases, half)
        with ProcessPoolExecutor(max_workers=max(1, min(workers, len(cases)))) as ex:
            parts = list(ex.map(case_points, cases))
        out[name] = np.concatenate(parts)
        print(f"{name} {half}: {len(out[name])} points", flush=True)
    return out


def study(points: dict[str, np.ndarray]) -> None:
    """Leave one suite out: the classifier's and the rules' separation of contact points."""
    from sklearn.ensemble import HistGradientBoostingClassifier
    from sklearn.metrics import roc_auc_score

    nf = len(FEATURES)
    print("suite | points (contact, other, under hovers >= 25 mm) | AUC rules, classifier | "
          "contact points passed at the rules' share of others: rules, classifier | "
          "hover >= 25 mm points passed: rules, classifier")
    for test, rows in points.items():
        train = np.concatenate([r for k, r in points.items() if k != test])
        train = train[train[:, nf + 1] >= 0]
        clf = HistGradientBoostingClassifier(max_iter=150, max_leaf_nodes=15, random_state=0)
        clf.fit(train[:, :nf], train[:, nf + 1])
        r = rows[rows[:, nf + 1] >= 0]
        y, w, high = r[:, nf + 1] == 1, r[:, nf], r[:, nf + 2] == 1
        if y.all() or not y.any():
            print(f"{test} | {len(r)} points, one class only: skipped")
            continue
        prob = clf.predict_proba(r[:, :nf])[:, 1]
        share = float(np.mean(w[~y] > 0))
        thr = float(np.quantile(prob[~y], 1.0 - share)) if share > 0 else 1.0
        print(f"{test} | {len(r)} ({y.sum()}, {(~y).sum()}, {high.sum()}) | "
              f"{roc_auc_score(y, w):.3f}, {roc_auc_score(y, prob):.3f} | "
              f"{np.mean(w[y] > 0):.3f}, {np.mean(prob[y] > thr):.3f} (others {share:.3f}) | "
              f"{np.mean(w[high] > 0):.3f}, {np.mean(prob[high] > thr):.3f}")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--suites", required=True, help="comma-separated suite names (2 or more)")
    ap.add_argument("--half", default="tune", choices=("tune", "held-out", "all"))
    ap.add_argument("--workers", type=int, default=default_workers())
    ap.add_argument("--out", help="also write the points to this .npz (one array per suite)")
    a = ap.parse_args(argv)
    suites = [s for s in a.suites.split(",") if s]
    if len(suites) < 2:
        ap.error("--suites needs two suites or more (each is scored by a fit on the others)")
    points = collect(suites, a.half, a.workers)
    if a.out:
        np.savez_compressed(a.out, **{k.replace("-", "_"): v for k, v in points.items()},
                            features=np.array(FEATURES))
    try:
        import sklearn  # noqa: F401
    except ImportError:
        print("evidence_study: the classifier needs scikit-learn; install it with "
              "pip install -e '.[study]' (the points were collected)", file=sys.stderr)
        return 1
    study(points)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
