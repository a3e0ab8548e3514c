"""Frozen per-stage configuration, with units in the names, loadable from and savable to TOML.

Every field has a documented default; ``validate()`` raises :class:`ConfigError` naming the
allowed range. A TOML file has one table per stage (``[surface]``, ``[regions]``, ...), and may
leave out anything that keeps its default.

The package's modules: ``stages`` (surface, regions, touch points, adapt, the path filter),
``tracking`` (tracking) and ``file`` (:class:`PipelineConfig`, reading and writing TOML);
every name is imported from here: ``from depthtouch.config import PipelineConfig``.
"""

from __future__ import annotations

from ..errors import ConfigError
from .file import PipelineConfig, config_from_dict, config_to_dict, dump_config, load_config
from .stages import AdaptConfig, FilterConfig, RegionConfig, SurfaceConfig, TouchPointConfig
from .tracking import TrackingConfig

__all__ = [
    "AdaptConfig",
    "ConfigError",
    "FilterConfig",
    "PipelineConfig",
    "RegionConfig",
    "SurfaceConfig",
    "TouchPointConfig",
    "TrackingConfig",
    "config_from_dict",
    "config_to_dict",
    "dump_config",
    "load_config",
]
