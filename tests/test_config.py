"""Configuration: defaults, `replace`, TOML round trip, and one-line errors naming the range."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import pytest

from depthtouch.config import (
    PipelineConfig,
    config_from_dict,
    config_to_dict,
    dump_config,
    load_config,
)
from depthtouch.errors import ConfigError, DepthTouchError


def _roundtrip(cfg: PipelineConfig, tmp_path: Path) -> PipelineConfig:
    p = tmp_path / "cfg.toml"
    p.write_text(dump_config(cfg), encoding="utf-8")
    return load_config(p)


def _numeric_fields() -> list[tuple[str, str, Any]]:
    """(section, field, default) of every number in every stage config."""
    out = []
    cfg = PipelineConfig()
    for stage in dataclasses.fields(cfg):
        for f in dataclasses.fields(getattr(cfg, stage.name)):
            default = getattr(getattr(cfg, stage.name), f.name)
            is_number = isinstance(default, (int, float)) and not isinstance(default, bool)
            if is_number or f.name.endswith("frames"):
                out.append((stage.name, f.name, default))
    return out


def test_defaults_are_valid_and_frozen(tmp_path: Path) -> None:
    cfg = PipelineConfig()
    assert cfg.validate() is cfg
    with pytest.raises(dataclasses.FrozenInstanceError):
        cfg.surface.learn_s = 2.0  # type: ignore[misc]
    empty = tmp_path / "empty.toml"
    empty.write_text("")
    assert load_config(empty) == cfg
    partial = tmp_path / "partial.toml"
    partial.write_text("[regions]\ntu_mm = 30\n")  # an int where a float is wanted is fine
    loaded = load_config(partial)
    assert loaded.regions.tu_mm == 30.0 and isinstance(loaded.regions.tu_mm, float)
    assert loaded.surface == cfg.surface


CHANGES: list[dict[str, dict[str, Any]]] = [
    {},
    {"surface": {"learn_s": 0.5, "statistic": "mode"}},
    {"surface": {"learn_frames": 12}},
    {"regions": {"tu_mm": 30.0, "tl_floor_mm": 3.5, "open_px": 1}},
    {"touchpoints": {"method": "paper", "paper_ds_px": 9}},
    {"tracking": {"gate_px": 12.5, "down_frames": 1, "up_frames": 5}},
    {"filter": {"name": "one_euro", "params": {"min_cutoff_hz": 1.5, "beta": 0.02}}},
    {"filter": {"name": 'we"ird\\name\n\t\x7f', "params": {"a b": 1.0, "x.y": 2.0, "": 3.0,
                                                           "ü": -4.5, "1": 1e-300}}},
]


@pytest.mark.parametrize("changes", CHANGES)
def test_dump_then_load_gives_the_same_config(changes: dict[str, dict[str, Any]],
                                              tmp_path: Path) -> None:
    cfg = PipelineConfig().replace(**changes)
    for section, values in changes.items():
        for k, v in values.items():
            assert getattr(getattr(cfg, section), k) == v
    again = _roundtrip(cfg, tmp_path)
    assert again == cfg
    assert config_to_dict(again) == config_to_dict(cfg)
    assert dump_config(again) == dump_config(cfg)


def test_replace_keeps_other_values_and_does_not_mutate() -> None:
    base = PipelineConfig()
    changed = base.replace(regions={"tu_mm": 30.0})
    assert base.regions.tu_mm == 25.0 and changed.regions.tu_mm == 30.0
    assert changed.regions.noise_k == base.regions.noise_k
    assert changed.surface == base.surface
    assert changed.replace(regions={"tu_mm": 25.0}) == base


@pytest.mark.parametrize(
    ("changes", "needle"),
    [
        ({"surfaces": {}}, "unknown config section [surfaces]"),
        ({"regions": {"tu": 3}}, "unknown key regions.tu; allowed:"),
        ({"regions": 5}, "takes a mapping"),
        ({"regions": {"tu_mm": "high"}}, "must be a number"),
        ({"regions": {"tu_mm": True}}, "must be a number"),
        ({"regions": {"open_px": 2.0}}, "must be a whole number"),
        ({"regions": {"open_px": 4}}, "regions.open_px = 4 must be odd"),
        ({"surface": {"statistic": 3}}, "must be a str"),
        ({"regions": {"tu_mm": 300.0}}, "allowed (0.0, 200.0]"),
        ({"regions": {"tu_mm": 3.0}}, "must be above regions.tl_floor_mm"),
        ({"touchpoints": {"touch_off_mm": 10.0}}, "allowed [14.0, 200.0]"),
        ({"touchpoints": {"method": "magic"}}, "use extremity or paper"),
        ({"filter": {"params": {"beta": "x"}}}, "must be a number"),
        ({"filter": {"params": {"beta": float("inf")}}}, "must be a finite number"),
        ({"filter": {"params": 3}}, "table of numbers"),
    ],
)
def test_replace_errors(changes: dict[str, Any], needle: str) -> None:
    with pytest.raises(ConfigError) as e:
        PipelineConfig().replace(**changes)
    assert needle in str(e.value)
    assert "\n" not in str(e.value)


@pytest.mark.parametrize(("section", "key", "default"), _numeric_fields(),
                         ids=[f"{s}.{k}" for s, k, _ in _numeric_fields()])
@pytest.mark.parametrize("value", [1e12, -1e12, float("nan")], ids=["huge", "negative", "nan"])
def test_every_number_is_range_checked_and_the_message_names_the_range(
    section: str, key: str, default: Any, value: float
) -> None:
    if isinstance(default, int) or default is None:  # whole-number fields: NaN is not one
        value = int(value) if value == value else -1
    with pytest.raises(ConfigError) as e:
        config_from_dict({section: {key: value}})
    msg = str(e.value)
    assert "\n" not in msg
    assert f"{section}.{key}" in msg or "must be above" in msg
    assert "allowed [" in msg or "allowed (" in msg or "must be above" in msg, msg


@pytest.mark.parametrize(
    ("text", "needle"),
    [
        ("[surface\n", "not valid TOML"),
        ("surface = 3\n", "must be a table"),
        ("[[surface]]\nlearn_s = 1.0\n", "must be a table"),
        ("[surface]\nlearn_s = 1979-05-27\n", "must be a number"),
        ("[surface]\nlearn_s = '1.0'\n", "must be a number"),
        ("[surface]\nlearn_s = 1e400\n", "allowed (0.0, 60.0]"),
        ("[surface]\nlearn_s = " + "9" * 400 + "\n", "allowed (0.0, 60.0]"),
        ("[surface]\nlearn_frames = 1.5\n", "must be a whole number"),
        ("[surface]\nlearn_frames = " + "9" * 400 + "\n", "allowed [2, 10000]"),
        ("[tracking]\ndown_frames = 99\n", "allowed [1, 30]"),
        ("[filter]\nname = 7\n", "must be a str"),
        ("[filter.params.a]\nb = 1\n", "must be a number"),
        ("[filter.params]\nbeta = " + "9" * 400 + "\n", "must be a finite number"),
        ("[extra]\n", "unknown config section [extra]"),
        ("[regions]\ntu_mm = 20.0\nTu_mm = 2.0\n", "unknown key regions.Tu_mm"),
        ("x = [" * 3000 + "]" * 3000, "not valid TOML"),
    ],
    ids=["syntax", "scalar section", "array of tables", "date", "string", "float overflow",
         "huge int", "float frames", "huge frames", "int range", "name type", "nested params",
         "huge param", "unknown section", "unknown key", "deep nesting"],
)
def test_load_config_errors(text: str, needle: str, tmp_path: Path) -> None:
    p = tmp_path / "c.toml"
    p.write_text(text, encoding="utf-8")
    with pytest.raises(ConfigError) as e:
        load_config(p)
    msg = str(e.value)
    assert needle in msg or (needle == "not valid TOML" and "nests too deeply" in msg), msg
    assert "\n" not in msg


@pytest.mark.parametrize(
    ("make", "needle"),
    [
        (lambda d: d / "missing.toml", "does not exist"),
        (lambda d: d, "cannot read config file"),
        (lambda d: _bytes(d / "c.toml", b"\xff\xfe[surface]"), "UTF-8"),
    ],
    ids=["missing", "folder", "not utf-8"],
)
def test_load_config_file_errors(make: Any, needle: str, tmp_path: Path) -> None:
    with pytest.raises(DepthTouchError) as e:
        load_config(make(tmp_path))
    assert isinstance(e.value, ConfigError) and needle in str(e.value)
    assert "\n" not in str(e.value)


def _bytes(p: Path, data: bytes) -> Path:
    p.write_bytes(data)
    return p


@pytest.mark.parametrize("data", [[], "surface", 3, None])
def test_config_from_dict_needs_a_table(data: Any) -> None:
    with pytest.raises(ConfigError, match="table of sections"):
        config_from_dict(data)


def test_config_from_dict_with_non_string_keys() -> None:
    with pytest.raises(ConfigError, match="unknown config section"):
        config_from_dict({1: {}, "x": {}})  # type: ignore[dict-item]
