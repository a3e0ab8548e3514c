"""All stages together (:class:`PipelineConfig`) and the config file: built from nested
mappings, read from TOML, written as TOML.

Part of :mod:`depthtouch.config`, which re-exports every name.
"""

from __future__ import annotations

import dataclasses
import sys
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..checks import show as _show
from ..errors import ConfigError
from .stages import AdaptConfig, FilterConfig, RegionConfig, SurfaceConfig, TouchPointConfig
from .tracking import TrackingConfig

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib


def _key(key: object, limit: int = 30) -> str:
    """A user's key for a one-line message: unquoted, whitespace collapsed, shortened."""
    text = " ".join(str(key).split())
    return text if len(text) <= limit else text[: limit - 3] + "..."


@dataclass(frozen=True)
class PipelineConfig:
    """All stages together; the unit of a TOML config file."""

    surface: SurfaceConfig = field(default_factory=SurfaceConfig)
    regions: RegionConfig = field(default_factory=RegionConfig)
    touchpoints: TouchPointConfig = field(default_factory=TouchPointConfig)
    tracking: TrackingConfig = field(default_factory=TrackingConfig)
    filter: FilterConfig = field(default_factory=FilterConfig)
    adapt: AdaptConfig = field(default_factory=AdaptConfig)

    def validate(self) -> PipelineConfig:
        for f in dataclasses.fields(self):
            getattr(self, f.name).validate()
        return self

    def replace(self, **stages: Any) -> PipelineConfig:
        """A copy with some stage fields changed: ``cfg.replace(regions={"tu_mm": 30})``."""
        changes = {}
        for name, values in stages.items():
            if name not in _STAGES:
                raise ConfigError(f"unknown config section [{name}]; use one of {sorted(_STAGES)}")
            if not isinstance(values, Mapping):
                raise ConfigError(
                    f"replace({name}=...) takes a mapping of field values, got "
                    f"{type(values).__name__}"
                )
            changes[name] = _build(_STAGES[name], name, {**_asdict(getattr(self, name)), **values})
        return dataclasses.replace(self, **changes).validate()


_STAGES: dict[str, type] = {
    "surface": SurfaceConfig,
    "regions": RegionConfig,
    "touchpoints": TouchPointConfig,
    "tracking": TrackingConfig,
    "filter": FilterConfig,
    "adapt": AdaptConfig,
}


def _asdict(obj: Any) -> dict[str, Any]:
    return {f.name: getattr(obj, f.name) for f in dataclasses.fields(obj)}


def _build(cls: type, section: str, values: Mapping[str, Any]) -> Any:
    if not isinstance(values, Mapping):
        raise ConfigError(
            f"config section [{section}] must be a table, got {type(values).__name__}"
        )
    names = {f.name: f for f in dataclasses.fields(cls)}
    unknown = sorted(set(values) - set(names), key=str)
    if unknown:
        raise ConfigError(
            f"unknown key {section}.{_key(unknown[0])}; allowed: {', '.join(sorted(names))}"
        )
    kwargs: dict[str, Any] = {}
    for k, v in values.items():
        default = getattr(cls(), k)
        if k == "params":
            if not isinstance(v, Mapping):
                raise ConfigError(f"{section}.params must be a table of numbers")
            kwargs[k] = dict(v)
        elif isinstance(default, bool) or (default is not None and isinstance(default, str)):
            if type(v) is not type(default):
                raise ConfigError(f"{section}.{k} = {_show(v)} must be a {type(default).__name__}")
            kwargs[k] = v
        elif isinstance(default, int) or (default is None and k.endswith("frames")):
            if v is not None and (not isinstance(v, int) or isinstance(v, bool)):
                raise ConfigError(f"{section}.{k} = {_show(v)} must be a whole number")
            kwargs[k] = v
        elif isinstance(default, float):
            if not isinstance(v, (int, float)) or isinstance(v, bool):
                raise ConfigError(f"{section}.{k} = {_show(v)} must be a number")
            try:
                kwargs[k] = float(v)
            except OverflowError:  # an integer beyond float range: validate() names the range
                kwargs[k] = float("inf") if v > 0 else float("-inf")
        else:
            kwargs[k] = v
    return cls(**kwargs)


def config_from_dict(data: Mapping[str, Any]) -> PipelineConfig:
    """Build and validate a config from nested mappings (as parsed from TOML)."""
    if not isinstance(data, Mapping):
        raise ConfigError("a config must be a table of sections")
    unknown = sorted(set(data) - set(_STAGES), key=str)
    if unknown:
        raise ConfigError(
            f"unknown config section [{_key(unknown[0])}]; use one of {sorted(_STAGES)}"
        )
    stages = {name: _build(cls, name, data.get(name, {})) for name, cls in _STAGES.items()}
    return PipelineConfig(**stages).validate()


def config_to_dict(cfg: PipelineConfig) -> dict[str, dict[str, Any]]:
    out: dict[str, dict[str, Any]] = {}
    for name in _STAGES:
        d = _asdict(getattr(cfg, name))
        out[name] = {k: (dict(v) if isinstance(v, Mapping) else v) for k, v in d.items()
                     if v is not None}
    return out


def load_config(path: str | Path) -> PipelineConfig:
    """Read a TOML config file; a missing or malformed file raises ConfigError."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigError(f"config file {p} does not exist; check the path") from None
    except (OSError, UnicodeDecodeError) as e:
        raise ConfigError(f"cannot read config file {p}: {e}; give a UTF-8 TOML file") from e
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise ConfigError(f"config file {p} is not valid TOML ({e}); fix the syntax") from e
    except RecursionError:  # absurdly deep nesting of arrays or inline tables
        raise ConfigError(f"config file {p} nests too deeply; fix the syntax") from None
    return config_from_dict(data)


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)
    if isinstance(v, str):
        return _toml_string(v)
    raise ConfigError(f"cannot write {_show(v)} to TOML")


_TOML_ESCAPES = {'"': '\\"', "\\": "\\\\", "\b": "\\b", "\t": "\\t", "\n": "\\n", "\f": "\\f",
                 "\r": "\\r"}


def _toml_string(text: str) -> str:
    """A TOML basic string: quotes, backslashes and control characters escaped."""
    out = []
    for c in text:
        if c in _TOML_ESCAPES:
            out.append(_TOML_ESCAPES[c])
        elif ord(c) < 0x20 or ord(c) == 0x7F:
            out.append(f"\\u{ord(c):04x}")
        else:
            out.append(c)
    return '"' + "".join(out) + '"'


def _toml_key(key: str) -> str:
    """A bare key when TOML allows one, else a quoted key."""
    bare = key != "" and all(c.isascii() and (c.isalnum() or c in "-_") for c in key)
    return key if bare else _toml_string(key)


def dump_config(cfg: PipelineConfig) -> str:
    """The config as TOML text (round-trips through :func:`load_config`)."""
    lines: list[str] = []
    for section, values in config_to_dict(cfg).items():
        lines.append(f"[{section}]")
        nested = {k: v for k, v in values.items() if isinstance(v, dict)}
        for k, v in values.items():
            if k not in nested:
                lines.append(f"{_toml_key(k)} = {_toml_value(v)}")
        for k, v in nested.items():
            lines.append(f"[{section}.{_toml_key(k)}]")
            lines.extend(f"{_toml_key(kk)} = {_toml_value(vv)}" for kk, vv in v.items())
        lines.append("")
    return "\n".join(lines)
