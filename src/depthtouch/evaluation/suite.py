"""The evaluation suite: simulator scenes with fixed seeds, rendered on demand and cached.

A suite file (TOML; the committed one is ``sim/suites/default.toml``) lists groups of cases; each
group is a grid of scenes x cameras x distances x surfaces x tilts x hands x seeds::

    [suite]
    name = "default"
    gate_mm = 20.0

    [[group]]
    name = "scenes"
    scenes = "all"                 # or a list of scene names
    cameras = ["kinect-v2"]        # or "all"
    distances_m = [1.0]
    surfaces = ["plane"]           # default ["plane"]
    tilts_deg = [0.0]              # default [0.0]
    hands = ["capsule"]            # default ["capsule"]; or "anatomic" (docs/simulator.md)
    pitches_deg = [60.0]           # optional: every lead finger at this pitch (default: drawn)
    motion_ms = 12.0               # optional: ToF motion mixing over this span (default 0: none)
    skin_noise = 1.5               # optional: noise of what stands on the surface x this (1: none)
    body = true                    # optional: arms go on into a body that leaves the view
    seeds = [1]
    tags = ["quick"]               # optional: subsets a run may select

Recordings are rendered in memory by :func:`depthtouch.sim.render_scene` when a case runs:
rendering costs 1-3 s of CPU per recording, less than reading a compressed cache file
(about 1.3 s) and far less than writing one (about 25 s). With ``cache`` (``depthtouch eval
--suite default --cache``) the recordings and truths are kept under ``<cache>/suite/``
(``.cache/depthtouch`` unless ``DEPTHTOUCH_CACHE`` is set), keyed by a hash of the case
parameters, the package version and the simulator's source (a changed simulator renders again),
for replaying them with other tools; the least recently used go when the folder passes
``$DEPTHTOUCH_CACHE_MAX_GB`` (50 GB; :mod:`depthtouch.evaluation.cachesize`). Nothing here is
committed but the suite file. Running the sensor over the cases is
:mod:`depthtouch.evaluation.suiterun`.
"""

from __future__ import annotations

import dataclasses
import hashlib
import itertools
import json
import os
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .. import __version__
from ..errors import ConfigError
from .cachesize import cache_limit_bytes, mark_used, prune
from .metrics import GATE_MM

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

SUITES_DIR = Path(__file__).parent.parent / "sim" / "suites"
SURFACES = ("plane", "cylinder-convex", "cylinder-concave")


@dataclass(frozen=True)
class SuiteCase:
    """One recording of the suite: the keywords of :func:`depthtouch.sim.render_scene`.

    distance_m: camera to surface (m); tilt_deg: surface tilt (deg); fps: frame rate (Hz);
    pitch_deg: every lead finger at this angle to the surface (deg), None: the scene's own.
    motion_ms: the span of the camera's raw exposures (ms; 0: none), see ``render_scene``.
    skin_noise: the temporal noise of what stands on the surface times this, and the noise's
    growth with the incidence angle (1: none), see ``render_scene``.
    body: arms go on past the shoulder into a body that leaves the view, see ``render_scene``.
    drop_rate: frames the camera never delivers (0: none), see ``render_scene``.
    breathing_mm: the whole frame moves at once by about this (0: none), see ``render_scene``.
    edge_mm: the surface ends inside the view, and beyond its edge lies this much farther (0:
    the surface fills the view), see ``render_scene``.
    empty_s: the rendered recording's first frames taken away so that its surface lies empty
    this long (s) before anything comes into view (0: as rendered; not a render setting: the
    cache keeps the recording as rendered), see :mod:`depthtouch.evaluation.emptystart`.
    """

    scene: str
    camera: str
    distance_m: float
    surface: str = "plane"
    tilt_deg: float = 0.0
    seed: int = 0
    fps: float = 30.0
    group: str = ""
    hand: str = "capsule"
    resolution_scale: float = 1.0
    pitch_deg: float | None = None
    noise_scale: float = 1.0
    motion_ms: float = 0.0
    skin_noise: float = 1.0
    body: bool = False
    drop_rate: float = 0.0
    breathing_mm: float = 0.0
    empty_s: float = 0.0
    edge_mm: float = 0.0

    @property
    def label(self) -> str:
        surf = "" if self.surface == "plane" else f"/{self.surface}"
        tilt = f"/tilt{self.tilt_deg:g}" if self.tilt_deg else ""
        hand = "" if self.hand == "capsule" else f"/{self.hand}"
        res = "" if self.resolution_scale == 1.0 else f"@x{self.resolution_scale:g}"
        pitch = "" if self.pitch_deg is None else f"/pitch{self.pitch_deg:g}"
        noise = "" if self.noise_scale == 1.0 else f"/noise{self.noise_scale:g}"
        motion = "" if self.motion_ms == 0.0 else f"/motion{self.motion_ms:g}"
        skin = "" if self.skin_noise == 1.0 else f"/skin{self.skin_noise:g}"
        body = "/body" if self.body else ""
        drop = "" if self.drop_rate == 0.0 else f"/drop{self.drop_rate:g}"
        breath = "" if self.breathing_mm == 0.0 else f"/breathe{self.breathing_mm:g}"
        empty = "" if self.empty_s == 0.0 else f"/empty{self.empty_s:g}"
        edge = "" if self.edge_mm == 0.0 else f"/edge{self.edge_mm:g}"
        return (f"{self.scene}/{self.camera}{res}/{self.distance_m:g}m{surf}{tilt}{hand}"
                f"{pitch}{noise}{motion}{skin}{body}{drop}{breath}{edge}{empty}/s{self.seed}")

    @property
    def rendered(self) -> SuiteCase:
        """The case as rendered and cached (without what is applied after: ``empty_s``)."""
        return self if self.empty_s == 0.0 else dataclasses.replace(self, empty_s=0.0)

    def render_kwargs(self) -> dict[str, Any]:
        kw: dict[str, Any] = {"camera": self.camera, "distance_m": self.distance_m,
                              "tilt_deg": self.tilt_deg, "surface": self.surface,
                              "seed": self.seed, "fps": self.fps}
        if self.hand != "capsule":
            kw["hand"] = self.hand
        if self.resolution_scale != 1.0:  # (absent at 1: the cache keys stay as they were)
            kw["resolution_scale"] = self.resolution_scale
        if self.pitch_deg is not None:  # (absent when drawn: the cache keys stay as they were)
            kw["pitch_deg"] = self.pitch_deg
        if self.noise_scale != 1.0:  # (absent at 1: the cache keys stay as they were)
            kw["noise_scale"] = self.noise_scale
        if self.motion_ms != 0.0:  # (absent at 0: the cache keys stay as they were)
            kw["motion_ms"] = self.motion_ms
        if self.skin_noise != 1.0:  # (absent at 1: the cache keys stay as they were)
            kw["skin_noise"] = self.skin_noise
        if self.body:  # (absent without: the cache keys stay as they were)
            kw["body"] = True
        if self.drop_rate != 0.0:  # (absent at 0: the cache keys stay as they were)
            kw["drop_rate"] = self.drop_rate
        if self.breathing_mm != 0.0:  # (absent at 0: the cache keys stay as they were)
            kw["breathing_mm"] = self.breathing_mm
        if self.edge_mm != 0.0:  # (absent at 0: the cache keys stay as they were)
            kw["edge_mm"] = self.edge_mm
        return kw

    def cache_key(self) -> str:
        """Hash of the scene parameters, the package version and the simulator source."""
        params = {"scene": self.scene, **self.render_kwargs(), "noise": True}
        text = json.dumps(params, sort_keys=True) + __version__ + _sim_digest()
        return hashlib.sha256(text.encode()).hexdigest()[:16]


@dataclass(frozen=True)
class Suite:
    """A loaded suite: its cases (deduplicated, in file order) and the tags of each."""

    name: str
    gate_mm: float
    cases: tuple[SuiteCase, ...]
    tags: dict[SuiteCase, frozenset[str]]

    def select(self, subset: str | None = None) -> list[SuiteCase]:
        """All cases, or those of the groups tagged ``subset``; ConfigError when none is."""
        if subset is None or subset == "all":
            return list(self.cases)
        chosen = [c for c in self.cases if subset in self.tags[c]]
        if not chosen:
            known = sorted({t for ts in self.tags.values() for t in ts})
            raise ConfigError(
                f"suite {self.name} has no subset {subset!r}; use one of {known + ['all']}"
            )
        return chosen

    def at_fps(self, fps: float | None) -> Suite:
        """The same cases rendered at ``fps`` (Hz, [1, 120]) instead of their own rate (None:
        this suite). Halves stay the same: they split by seed and placement."""
        if fps is None:
            return self
        from ..sim.render import check_render_args

        check_render_args(fps, 0)
        return self._with(fps=float(fps))

    def at_resolution(self, scale: float | None) -> Suite:
        """The same cases seen by their cameras at ``scale`` times the resolution, with the same
        field of view ([0.25, 3]; None: this suite). Halves stay the same."""
        if scale is None:
            return self
        if not 0.25 <= scale <= 3.0:
            raise ConfigError(f"resolution scale {scale!r} is out of range; allowed [0.25, 3]")
        return self._with(resolution_scale=float(scale))

    def at_noise(self, scale: float | None) -> Suite:
        """The same cases with every camera's axial noise ``scale`` times its own ([0.25, 4];
        None: this suite). Halves stay the same."""
        if scale is None:
            return self
        if not 0.25 <= scale <= 4.0:
            raise ConfigError(f"noise scale {scale!r} is out of range; allowed [0.25, 4]")
        return self._with(noise_scale=float(scale))

    def with_body(self, on: bool = True) -> Suite:
        """The same cases with every arm going on into a body that leaves the view (``body``,
        see :func:`depthtouch.sim.render_scene`; False: this suite). Halves stay the same."""
        return self._with(body=True) if on else self

    def with_drops(self, rate: float | None) -> Suite:
        """The same cases with frames the camera never delivers (``drop_rate``, see
        :func:`depthtouch.sim.render_scene`, [0, 0.2]; None: this suite). Halves stay the same."""
        if rate is None:
            return self
        from ..sim.drops import check_drop_rate

        return self._with(drop_rate=check_drop_rate(rate))

    def with_breathing(self, scale_mm: float | None) -> Suite:
        """The same cases with frames that move as a whole (``breathing_mm``, see
        :func:`depthtouch.sim.render_scene`, [0, 10] mm; None: this suite). Halves stay the
        same."""
        if scale_mm is None:
            return self
        from ..sim.breathing import check_breathing

        return self._with(breathing_mm=check_breathing(scale_mm))

    def with_edge(self, drop_mm: float | None) -> Suite:
        """The same cases on a surface that ends inside the view (``edge_mm``, see
        :func:`depthtouch.sim.render_scene`, 0 or [100, 1500] mm; None: this suite). Halves
        stay the same."""
        if drop_mm is None:
            return self
        from ..sim.edge import check_edge

        return self._with(edge_mm=check_edge(drop_mm))

    def with_empty_start(self, empty_s: float | None) -> Suite:
        """The same cases with their empty start shortened to ``empty_s`` seconds (``empty_s``,
        [0.2, 10] s, see :mod:`depthtouch.evaluation.emptystart`; None: this suite). Halves stay
        the same."""
        if empty_s is None:
            return self
        from .emptystart import check_empty_s

        return self._with(empty_s=check_empty_s(empty_s))

    def _with(self, **changes: Any) -> Suite:
        """Every case with these render settings changed; tags and order kept."""
        moved = {c: dataclasses.replace(c, **changes) for c in self.cases}
        return Suite(self.name, self.gate_mm, tuple(dict.fromkeys(moved.values())),
                     {moved[c]: t for c, t in self.tags.items()})


# --- loading -------------------------------------------------------------------------------------
def _sim_names() -> tuple[tuple[str, ...], tuple[str, ...]]:
    """Every scene and camera a suite may name ("all" means the default ones only)."""
    from ..sim import ALL_SCENES, CAMERAS, HARD_CAMERAS

    return ALL_SCENES, tuple(CAMERAS) + tuple(HARD_CAMERAS)


def _hand_styles() -> tuple[str, ...]:
    from ..sim.hand import HAND_STYLES

    return HAND_STYLES


def _pitch_range() -> tuple[float, float]:
    from ..sim import PITCH_RANGE_DEG

    return PITCH_RANGE_DEG


def _all_default(group: dict[str, Any], key: str, names: list[Any]) -> list[Any]:
    from ..sim import CAMERAS, SCENES

    if group.get(key) == "all":
        return list(SCENES if key == "scenes" else CAMERAS)
    return names


def _list(group: dict[str, Any], key: str, default: list[Any] | None, where: str,
          allowed: Sequence[str] | None = None) -> list[Any]:
    v = group.get(key, default)
    if v is None:
        raise ConfigError(f"{where}: {key} is missing; add e.g. {key} = [...]")
    if v == "all" and allowed is not None:
        return list(allowed)
    if not isinstance(v, list) or not v:
        raise ConfigError(f"{where}: {key} must be a non-empty list (or \"all\")")
    if allowed is not None:
        bad = [x for x in v if x not in allowed]
        if bad:
            raise ConfigError(f"{where}: {key} has unknown {bad[0]!r}; use {', '.join(allowed)}")
    return v


def _numbers(v: list[Any], key: str, where: str, lo: float, hi: float) -> list[float]:
    for x in v:
        if isinstance(x, bool) or not isinstance(x, (int, float)) or not lo <= x <= hi:
            raise ConfigError(f"{where}: {key} value {x!r} is out of range; allowed [{lo}, {hi}]")
    return [float(x) for x in v]


def suite_from_dict(data: dict[str, Any], where: str = "suite") -> Suite:
    """Build a suite from parsed TOML; ConfigError (one line) on anything invalid."""
    scenes, cameras = _sim_names()
    head = data.get("suite", {})
    if not isinstance(head, dict):
        raise ConfigError(f"{where}: [suite] must be a table")
    name = str(head.get("name", "suite"))
    gate = head.get("gate_mm", GATE_MM)
    if isinstance(gate, bool) or not isinstance(gate, (int, float)) or not 0 < gate <= 200:
        raise ConfigError(f"{where}: gate_mm = {gate!r} is out of range; allowed (0, 200]")
    groups = data.get("group")
    if not isinstance(groups, list) or not groups:
        raise ConfigError(f"{where}: no [[group]] tables; add at least one group of cases")
    cases: dict[SuiteCase, tuple[SuiteCase, set[str]]] = {}  # keyed without the group name
    for i, g in enumerate(groups):
        if not isinstance(g, dict):
            raise ConfigError(f"{where}: group {i} must be a table")
        gname = str(g.get("name", f"group{i}"))
        gw = f"{where}: group {gname}"
        known = {"name", "scenes", "cameras", "distances_m", "surfaces", "tilts_deg", "seeds",
                 "fps", "tags", "hands", "pitches_deg", "motion_ms", "skin_noise", "body",
                 "drop_rate", "breathing_mm", "edge_mm"}
        unknown = sorted(set(g) - known)
        if unknown:
            raise ConfigError(
                f"{gw}: unknown key {unknown[0]!r}; allowed: {', '.join(sorted(known))}"
            )
        sc = _all_default(g, "scenes", _list(g, "scenes", None, gw, scenes))
        cams = _all_default(g, "cameras", _list(g, "cameras", None, gw, cameras))
        dists = _numbers(_list(g, "distances_m", None, gw), "distances_m", gw, 0.3, 5.0)
        surfs = _list(g, "surfaces", ["plane"], gw, SURFACES)
        tilts = _numbers(_list(g, "tilts_deg", [0.0], gw), "tilts_deg", gw, 0.0, 80.0)
        hands = _list(g, "hands", ["capsule"], gw, _hand_styles())
        pitches: list[float | None] = (
            [None] if "pitches_deg" not in g
            else list(_numbers(_list(g, "pitches_deg", None, gw), "pitches_deg", gw,
                               *_pitch_range())))
        seeds = _list(g, "seeds", [0], gw)
        if any(isinstance(s, bool) or not isinstance(s, int) or s < 0 for s in seeds):
            raise ConfigError(f"{gw}: seeds must be whole numbers >= 0")
        fps = _numbers([g.get("fps", 30.0)], "fps", gw, 1.0, 1000.0)[0]
        motion = _numbers([g.get("motion_ms", 0.0)], "motion_ms", gw, 0.0, 50.0)[0]
        skin = _numbers([g.get("skin_noise", 1.0)], "skin_noise", gw, 1.0, 4.0)[0]
        drop = _numbers([g.get("drop_rate", 0.0)], "drop_rate", gw, 0.0, 0.2)[0]
        breath = _numbers([g.get("breathing_mm", 0.0)], "breathing_mm", gw, 0.0, 10.0)[0]
        edge = g.get("edge_mm", 0.0)
        if edge != 0.0:
            from ..sim.edge import check_edge

            try:
                edge = check_edge(edge)
            except ConfigError as e:
                raise ConfigError(f"{gw}: {e}") from None
        body = g.get("body", False)
        if not isinstance(body, bool):
            raise ConfigError(f"{gw}: body = {body!r} must be true or false")
        tags = g.get("tags", [])
        if not isinstance(tags, list) or not all(isinstance(t, str) for t in tags):
            raise ConfigError(f"{gw}: tags must be a list of names")
        for s in sc:
            for cam in cams:
                for d in dists:
                    for surf in surfs:
                        for tilt, hand, pitch, seed in itertools.product(tilts, hands, pitches,
                                                                         seeds):
                            c = SuiteCase(s, cam, d, surf, tilt, int(seed), fps, gname, hand,
                                          pitch_deg=pitch, motion_ms=motion,
                                          skin_noise=skin, body=body, drop_rate=drop,
                                          breathing_mm=breath, edge_mm=float(edge))
                            key = dataclasses.replace(c, group="")
                            cases.setdefault(key, (c, set()))[1].update(tags)
    ordered = [c for c, _ in cases.values()]
    return Suite(name, float(gate), tuple(ordered),
                 {c: frozenset(t) for c, t in cases.values()})


def load_suite(name_or_path: str | Path) -> Suite:
    """A committed suite by name (``default``) or a suite TOML file by path."""
    text = str(name_or_path)
    p = Path(text)
    if not p.suffix and not p.exists():
        p = SUITES_DIR / f"{text}.toml"
        if not p.is_file():
            known = sorted(q.stem for q in SUITES_DIR.glob("*.toml"))
            raise ConfigError(f"unknown suite {text!r}; use one of {known} or a .toml path")
    try:
        data = tomllib.loads(p.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ConfigError(f"suite file {p} does not exist; check the path") from None
    except (OSError, UnicodeDecodeError) as e:
        raise ConfigError(f"cannot read suite file {p} ({e}); give a UTF-8 TOML file") from e
    except tomllib.TOMLDecodeError as e:
        raise ConfigError(f"suite file {p} is not valid TOML ({e}); fix the syntax") from e
    return suite_from_dict(data, str(p))


# --- recordings ----------------------------------------------------------------------------------
def cache_root() -> Path:
    """``$DEPTHTOUCH_CACHE`` or ``.cache/depthtouch`` (relative to the working folder)."""
    return Path(os.environ.get("DEPTHTOUCH_CACHE", ".cache/depthtouch"))


_SIM_DIGEST: str | None = None


def _sim_digest() -> str:
    global _SIM_DIGEST
    if _SIM_DIGEST is None:
        h = hashlib.sha256()
        for p in sorted((Path(__file__).parent.parent / "sim").glob("*.py")):
            h.update(p.name.encode())
            h.update(p.read_bytes())
        _SIM_DIGEST = h.hexdigest()
    return _SIM_DIGEST


def recording_paths(case: SuiteCase, cache: Path | None = None) -> tuple[Path, Path]:
    """Where the cached recording and truth of ``case`` live (they may not exist yet)."""
    root = (cache or cache_root()) / "suite"
    case = case.rendered  # a shortened empty start reads the recording as rendered
    stem = f"{case.label.replace('/', '_')}-{case.cache_key()}"
    return root / f"{stem}.npz", root / f"{stem}.truth.json"


def ensure_recording(case: SuiteCase, cache: Path | None = None) -> tuple[Path, Path]:
    """Render the case unless it is cached; returns (recording .npz, truth .json)."""
    rec_path, truth_path = recording_paths(case, cache)
    limit = cache_limit_bytes()  # a malformed limit fails before anything is rendered
    if rec_path.is_file() and truth_path.is_file():
        mark_used(rec_path)
        return rec_path, truth_path
    from ..sim import render_scene, write_recording

    rec_path.parent.mkdir(parents=True, exist_ok=True)
    rec = render_scene(case.scene, **case.render_kwargs())
    # the recording's presence marks a complete entry, so it is renamed into place last; the
    # temporary name is per process because several runs may fill one cache at the same time
    part = rec_path.with_suffix(f".part{os.getpid()}.npz")
    try:
        write_recording(rec, part, truth_path)
        os.replace(part, rec_path)
    finally:
        part.unlink(missing_ok=True)
    if limit is not None:  # the least recently used recordings go (evaluation/cachesize.py)
        prune(rec_path.parent, limit, keep=rec_path)
    return rec_path, truth_path
