"""The machinery every path filter shares: the protocol, parameters with unit and range, and a
base class that keeps each touch's state in arrays (one update per frame for all touches).

A touch whose timestamp did not advance since its last update (a repeated or backwards
timestamp) is treated as "no time elapsed": it returns its previous output and its state is left
unchanged, so no ``dt`` is ever divided by zero. The filters themselves are in
:mod:`depthtouch.tracking.filters`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import ClassVar, Protocol, runtime_checkable

import numpy as np

from ..errors import ConfigError


@runtime_checkable
class TouchFilter(Protocol):
    """What the pipeline calls: one ``update`` per frame with the touches measured in it."""

    def update(self, ids: np.ndarray, xy_mm: np.ndarray, timestamp_s: float) -> np.ndarray: ...

    def drop(self, ids: np.ndarray) -> None: ...

    def reset(self) -> None: ...


@dataclass(frozen=True)
class Param:
    """One filter parameter: default, allowed range (lo, hi], or [lo, hi] when not lo_open."""

    default: float
    lo: float
    hi: float
    lo_open: bool = True

    def check(self, filter_name: str, name: str, value: float) -> float:
        v = float(value)
        bad = (v <= self.lo if self.lo_open else v < self.lo) or v > self.hi or not math.isfinite(v)
        if bad:
            lb = "(" if self.lo_open else "["
            raise ConfigError(
                f"filter.params.{name} = {value!r} is out of range for {filter_name}; "
                f"allowed {lb}{self.lo}, {self.hi}]"
            )
        return v


def smoothing_factor(dt_s: np.ndarray, cutoff_hz: np.ndarray | float) -> np.ndarray:
    """Weight of a new sample in a first-order low-pass: ``dt / (dt + tau)``, tau = 1/(2π fc).

    This is the 1€ filter's ``alpha``; dt_s > 0 gives a weight in (0, 1).
    """
    if isinstance(cutoff_hz, (int, float)):
        # one cutoff: tau as a float (the same double the array expression gives), one call less
        tau_s: np.ndarray | float = 1.0 / (2.0 * math.pi * float(cutoff_hz))
    else:
        tau_s = 1.0 / (2.0 * np.pi * np.asarray(cutoff_hz, dtype=np.float64))
    return np.asarray(dt_s / (dt_s + tau_s), dtype=np.float64)


class FilterBase:
    """Per-id state bookkeeping shared by all filters; subclasses supply the maths.

    State lives in one array with a row per active touch: the columns are the last output (mm,
    ``_out``), the time of the last update (s, ``_t``) and the named fields of ``_FIELDS``
    (``_state[name]``; each field is a vector per touch), all views of ``_buf``. ``_init`` fills
    the rows of new touches from their first measurement (their ``_t`` is already set);
    ``_step`` advances a copy of the rows whose dt > 0 (their fields in place) and returns
    their output.
    """

    name: ClassVar[str] = ""
    PARAMS: ClassVar[Mapping[str, Param]] = {}
    _FIELDS: ClassVar[Mapping[str, tuple[int]]] = {}
    # columns of the state rows: output x, y, time, then the fields in order (see __init_subclass__)
    _COLS: ClassVar[Mapping[str, slice]] = {}
    _WIDTH: ClassVar[int] = 3

    def __init_subclass__(cls, **kwargs: object) -> None:
        super().__init_subclass__(**kwargs)
        cols, start = {}, 3
        for k, (n,) in cls._FIELDS.items():
            cols[k] = slice(start, start + n)
            start += n
        cls._COLS, cls._WIDTH = cols, start

    def __init__(self, **params: float) -> None:
        unknown = sorted(set(params) - set(self.PARAMS))
        if unknown:
            valid = ", ".join(self.PARAMS) or "none (this filter takes no parameters)"
            raise ConfigError(
                f"unknown parameter filter.params.{unknown[0]} for {self.name}; valid: {valid}"
            )
        values = {k: p.default for k, p in self.PARAMS.items()}
        for k, v in params.items():
            values[k] = self.PARAMS[k].check(self.name, k, v)
        self.params: dict[str, float] = values
        self.reset()

    # --- bookkeeping -----------------------------------------------------------------------
    def reset(self) -> None:
        """Forget every touch."""
        self._rows: dict[int, int] = {}
        self._free: list[int] = []
        self._alloc(np.zeros((0, self._WIDTH)))

    def _alloc(self, buf: np.ndarray) -> None:
        self._buf = buf
        self._out = buf[:, 0:2]
        self._t = buf[:, 2]
        self._state = {k: buf[:, c] for k, c in self._COLS.items()}

    def drop(self, ids: np.ndarray) -> None:
        """Forget these ids (a touch went ``up``); unknown ids are ignored."""
        for i in np.asarray(ids, dtype=np.int64).reshape(-1).tolist():
            row = self._rows.pop(int(i), None)
            if row is not None:
                self._free.append(row)

    @property
    def active_ids(self) -> list[int]:
        """Ids that currently have state."""
        return sorted(self._rows)

    def _grow(self, need: int) -> None:
        cap = self._buf.shape[0]
        new_cap = max(8, 2 * cap, cap + need)
        self._free.extend(range(new_cap - 1, cap - 1, -1))
        self._alloc(np.concatenate([self._buf, np.zeros((new_cap - cap, self._WIDTH))]))

    def _lookup(self, ids: list[int]) -> tuple[np.ndarray, np.ndarray]:
        is_new = np.array([i not in self._rows for i in ids], dtype=bool)
        n_new = int(is_new.sum())
        if n_new > len(self._free):
            self._grow(n_new - len(self._free))
        for i, new in zip(ids, is_new.tolist(), strict=True):
            if new:
                self._rows[i] = self._free.pop()
        rows = np.array([self._rows[i] for i in ids], dtype=np.intp)
        return rows, is_new

    # --- the frame update ------------------------------------------------------------------
    def update(self, ids: np.ndarray, xy_mm: np.ndarray, timestamp_s: float) -> np.ndarray:
        """Filter the touches measured in one frame.

        ids: int (N,), distinct; xy_mm: float (N, 2) measured positions in mm; timestamp_s: the
        frame's time in seconds. Returns a new float64 (N, 2) array of filtered positions. An id
        without state starts fresh with its measurement; ids not passed keep their state.
        Inputs are never mutated.
        """
        # a handful of touches per frame: checks on plain Python values cost less than array
        # calls (each ~1 us) and raise the same errors
        id_arr = np.asarray(ids)
        xy = np.asarray(xy_mm, dtype=np.float64)
        int_kind = id_arr.dtype.kind in "iu"
        if id_arr.ndim != 1 or (
            id_arr.size and not (int_kind or np.issubdtype(id_arr.dtype, np.integer))
        ):
            raise ValueError(f"ids: expected integer shape (_,), got {id_arr.dtype} {id_arr.shape}")
        if xy.ndim != 2 or xy.shape[1] != 2 or xy.shape[0] != id_arr.shape[0]:
            raise ValueError(f"xy_mm: expected shape ({id_arr.shape[0]}, 2), got {xy.shape}")
        t = float(timestamp_s)
        if not math.isfinite(t):
            raise ValueError(f"timestamp_s must be finite, got {timestamp_s!r}")
        if not all(map(math.isfinite, xy.ravel().tolist())):
            raise ValueError("xy_mm must be finite; leave a missed touch out of the frame instead")
        id_list = id_arr.tolist() if int_kind else [int(i) for i in id_arr.tolist()]
        id_set = set(id_list)
        if len(id_set) != len(id_list):
            raise ValueError(f"ids must be distinct within a frame, got {id_list}")
        if not id_list:
            return np.zeros((0, 2))

        known = self._rows
        if id_set <= known.keys():
            # the usual frame: every touch known and time advanced: one gather, one scatter
            rows = np.array([known[i] for i in id_list], dtype=np.intp)
            s = self._buf.take(rows, axis=0)
            dt_s = t - s[:, 2]
            if min(dt_s.tolist()) > 0.0:
                out = self._step(s, xy, dt_s)
                s[:, 0:2] = out
                s[:, 2] = t
                self._buf[rows] = s
                return out
        rows, is_new = self._lookup(id_list)
        if is_new.any():
            new_rows = rows[is_new]
            self._out[new_rows] = xy[is_new]
            self._t[new_rows] = t  # before _init, which may read it
            self._init(new_rows, xy[is_new])
        old_rows, old_xy = rows[~is_new], xy[~is_new]
        dt_s = t - self._t[old_rows]
        moved = dt_s > 0.0  # dt <= 0: no time elapsed, keep the previous output and state
        if moved.any():
            step_rows = old_rows[moved]
            s = self._buf[step_rows]
            s[:, 0:2] = self._step(s, old_xy[moved], dt_s[moved])
            s[:, 2] = t
            self._buf[step_rows] = s
        return self._out[rows].copy()

    def _init(self, rows: np.ndarray, xy: np.ndarray) -> None:
        for a in self._state.values():
            a[rows] = 0.0

    def _step(self, s: np.ndarray, xy: np.ndarray, dt_s: np.ndarray) -> np.ndarray:
        """Advance the state rows ``s`` (a copy: output, time, fields) by dt_s > 0 to the
        measurements xy; update the fields of ``s`` in place, return the new outputs (a new
        array, not a view of ``xy``)."""
        raise NotImplementedError  # pragma: no cover - every filter defines it

    def __repr__(self) -> str:
        args = ", ".join(f"{k}={v:g}" for k, v in self.params.items())
        return f"{type(self).__name__}({args})"
