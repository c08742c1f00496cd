"""Results of pure geometric functions kept for the next call with the same geometry.

A study, a sweep or a bisection builds its scene again and again with another friction or
cohesion (`kgm.probabilistic`, the critical-friction search): the block polygons, their
overlap check and their edge contacts are the same each time, and their checks and searches
(shapely, a few hundred NumPy calls) cost as much as the rest of a small model's build. The
functions that do them are functions of the vertex coordinates alone; each keeps its last
results here under the exact bytes of its input (``key``), so a repeated geometry gets the very
result it got before, the same floats, and any other input (a coordinate one ulp away) is
computed afresh. A result is handed out as a copy (``GeometryMemo.get``): a caller may change
what it gets. Errors are never kept: bad input raises each time. ``scene_key`` says the same of
a whole scene but its joints' values: the work that reads a scene's geometry alone (kgm's block
system, a batch's sub-model) is done once for the samples that share it.
"""

from __future__ import annotations

import io
import pickle
import threading
from collections import OrderedDict
from typing import Any, Callable, Hashable, Optional

import numpy as np

#: entries each memo keeps (the most recently used); a study repeats one geometry, a scene's
#: polygons are a few hundred
DEFAULT_ENTRIES = 64
_NONE = object()  # no result kept


def key(*arrays) -> tuple:
    """The exact identity of the arrays (dtype, shape and bytes) and of any plain values."""
    out = []
    for a in arrays:
        if isinstance(a, np.ndarray):
            out.append((a.dtype.str, a.shape, a.tobytes()))
        else:
            out.append(a)
    return tuple(out)


class _Unkeyed(Exception):
    """A scene holds something whose identity its bytes do not say (a function)."""


class _KeyPickler(pickle.Pickler):
    """Pickles plain data only: a function (a time-varying load, a ground acceleration) stops it,
    since its name does not say what it computes."""

    def reducer_override(self, obj):
        # classes and NumPy's own rebuilders are how dataclasses and arrays are pickled; any
        # other callable is the user's
        if callable(obj) and not isinstance(obj, type) and obj not in _REBUILDERS:
            raise _Unkeyed
        return NotImplemented


#: the functions with which NumPy rebuilds a pickled array
_REBUILDERS = frozenset(np.zeros(1).__reduce_ex__(pickle.HIGHEST_PROTOCOL)[0:1] + np.zeros(1).__reduce_ex__(2)[0:1])


def scene_key(scene, *, without: tuple = ("joints",)) -> Optional[bytes]:
    """The exact identity of a scene's content but its joint table's strengths: the pickled
    bytes of every attribute but ``without`` (blocks with their vertices, materials, fixed flags,
    velocities, stresses and edge joints; joint overrides, points, loads, gravity, water, bolts,
    and any attribute added later), with the joint table's length. Two scenes with the same key
    differ at most in their joints' values (a study's samples built at other strengths: what
    depends on the geometry alone is made once for them, `kgm.build`, `kgm.judges.fused`). None
    where the scene holds a function (a load varying in time, a ground acceleration) or
    anything that does not pickle: such a scene is never taken for another. Bytes, not a hash:
    equal keys are equal content (a miss where equal content pickles otherwise, e.g. one
    material object for three blocks against three equal ones)."""
    state = {k: v for k, v in vars(scene).items() if k not in without}
    out = io.BytesIO()
    try:
        _KeyPickler(out, protocol=pickle.HIGHEST_PROTOCOL).dump(
            (type(scene), sorted(state.items()), len(getattr(scene, "joints", ()))))
    except (_Unkeyed, pickle.PicklingError, TypeError, AttributeError):
        return None
    return out.getvalue()


class GeometryMemo:
    """A bounded map from `key` to a result (least recently used dropped first)."""

    def __init__(self, entries: int = DEFAULT_ENTRIES):
        self.entries = entries
        self._kept: "OrderedDict[Hashable, Any]" = OrderedDict()
        self._lock = threading.Lock()
        self.hits = 0
        self.misses = 0

    def get(self, k: Hashable, compute: Callable[[], Any]) -> Any:
        """A copy of the result kept under ``k``, else ``compute()``'s, kept (and a copy given).
        Safe from several threads (a study's threaded workers): ``compute`` runs outside the lock."""
        with self._lock:
            kept = self._kept.get(k, _NONE)
            if kept is not _NONE:
                self._kept.move_to_end(k)
                self.hits += 1
                return _copy(kept)
            self.misses += 1
        value = compute()  # an error propagates and nothing is kept
        with self._lock:
            self._kept[k] = _copy(value)
            while len(self._kept) > self.entries:
                self._kept.popitem(last=False)
        return value

    def clear(self) -> None:
        with self._lock:
            self._kept.clear()
            self.hits = self.misses = 0

    def __len__(self) -> int:
        return len(self._kept)


def _copy(value):
    """A copy that shares nothing mutable with ``value`` (arrays, lists of tuples of numbers)."""
    if isinstance(value, np.ndarray):
        return value.copy()
    if isinstance(value, list):
        return [_copy(v) for v in value]
    if isinstance(value, tuple):
        return tuple(_copy(v) for v in value)
    if value is None or isinstance(value, (bool, int, float, str, np.generic)):
        return value
    if hasattr(value, "tocsr"):  # a SciPy sparse matrix: its arrays copied
        return value.copy()
    raise TypeError(f"GeometryMemo keeps arrays, sparse matrices, lists, tuples and numbers, not {type(value).__name__}")
