"""Checkpoints: a run saved between two steps, to be continued with identical results.

A checkpoint is one ``.npz`` file: the results recorded so far (every field of
`ddatai.results.Results`, so `load_results` reads it as a partial run), the `State` after the
last accepted step (every field, bit for bit), the run's targets and recording options, and a
fingerprint of the model it belongs to. ``simulate(scene, resume=path)`` rebuilds the model
from the same scene and parameters, checks the fingerprint, and carries on from that state: the
steps that follow depend only on the state and the model, so a run split by a checkpoint gives
the same numbers as one that was not (the wall-time columns of the step records aside).

Files are written to a temporary name and renamed, so an interrupted write never leaves a
truncated checkpoint. Plain NumPy; no pickles.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import signal
import threading
from pathlib import Path
from typing import Optional

import numpy as np

#: version of the checkpoint layout (a file of another version is refused)
FORMAT = 1


@dataclasses.dataclass(frozen=True, kw_only=True)
class RunTargets:
    """What a run was asked for, stored in its checkpoints."""

    duration: Optional[float]
    """Simulated time to reach [s], or None."""
    steps: Optional[int]
    """Number of steps to take (counted from the start of the run), or None."""
    record_every: int
    """A frame every this many steps [-]."""
    record_contacts: bool
    """Contacts recorded with each frame."""


def model_fingerprint(model) -> str:
    """A hash of everything in the model that a step reads (arrays, numbers, parameters); a
    time function (loads, ground acceleration) counts by its name only."""
    h = hashlib.sha256()
    for f in dataclasses.fields(model):
        value = getattr(model, f.name)
        h.update(f.name.encode())
        if isinstance(value, np.ndarray) and value.dtype != object:
            h.update(str(value.dtype).encode() + str(value.shape).encode())
            h.update(np.ascontiguousarray(value).tobytes())
        elif callable(value):
            h.update(getattr(value, "__qualname__", type(value).__name__).encode())
        elif isinstance(value, (tuple, list)):
            for v in value:
                h.update((getattr(v, "__qualname__", "fn") if callable(v) else repr(v)).encode())
        else:
            h.update(repr(value).encode())
    return h.hexdigest()


def _state_arrays(state) -> tuple[dict[str, np.ndarray], dict[str, str]]:
    """Every field of a `State` as named arrays, and how to rebuild each."""
    arrays: dict[str, np.ndarray] = {}
    kinds: dict[str, str] = {}
    for f in dataclasses.fields(state):
        value = getattr(state, f.name)
        key = f"checkpoint.state.{f.name}"
        if value is None:
            kinds[f.name] = "none"
        elif isinstance(value, bool):
            kinds[f.name], arrays[key] = "bool", np.array(value)
        elif isinstance(value, (int, np.integer)):
            kinds[f.name], arrays[key] = "int", np.array(value, dtype=np.int64)
        elif isinstance(value, (float, np.floating)):
            kinds[f.name], arrays[key] = "float", np.array(value, dtype=np.float64)
        elif isinstance(value, np.ndarray):
            kinds[f.name], arrays[key] = "array", value
        elif isinstance(value, dict):
            kinds[f.name] = "dict"
            for k, v in value.items():
                arrays[f"{key}.{k}"] = np.asarray(v)
        elif dataclasses.is_dataclass(value):
            kinds[f.name] = "dataclass:" + type(value).__name__
            for g in dataclasses.fields(value):
                arrays[f"{key}.{g.name}"] = np.asarray(getattr(value, g.name))
        else:
            raise TypeError(f"checkpoint: State.{f.name} of type {type(value).__name__} cannot be saved")
        if f.name in arrays and arrays[key].dtype == object:
            raise TypeError(f"checkpoint: State.{f.name} holds Python objects and cannot be saved")
    return arrays, kinds


def _state_from(data, kinds: dict[str, str], template):
    """Rebuild a `State` saved by `_state_arrays`; ``template`` (a State of the same model)
    gives the classes of nested fields."""
    values = {}
    for f in dataclasses.fields(template):
        kind = kinds.get(f.name)
        key = f"checkpoint.state.{f.name}"
        if kind is None:
            raise ValueError(f"checkpoint has no State.{f.name} (written by another version of ddatai)")
        if kind == "none":
            values[f.name] = None
        elif kind == "bool":
            values[f.name] = bool(data[key])
        elif kind == "int":
            values[f.name] = int(data[key])
        elif kind == "float":
            values[f.name] = float(data[key])
        elif kind == "array":
            values[f.name] = data[key]
        elif kind == "dict":
            prefix = key + "."
            values[f.name] = {k[len(prefix):]: data[k] for k in data.files if k.startswith(prefix)}
        else:
            cls = type(getattr(template, f.name))
            values[f.name] = cls(**{g.name: data[f"{key}.{g.name}"] for g in dataclasses.fields(cls)})
    return type(template)(**values)


def write_checkpoint(path, *, state, results, model, targets: RunTargets) -> Path:
    """Write a checkpoint of ``state`` (after its step) with the ``results`` recorded so far."""
    path = Path(path)
    arrays = {f.name: getattr(results, f.name) for f in dataclasses.fields(results)}
    state_arrays, kinds = _state_arrays(state)
    arrays.update(state_arrays)
    meta = {"format": FORMAT, "model": model_fingerprint(model), "kinds": kinds,
            "targets": dataclasses.asdict(targets)}
    arrays["checkpoint.meta"] = np.array(json.dumps(meta))
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "wb") as fh:
        np.savez(fh, **arrays)
    os.replace(tmp, path)
    return path


@dataclasses.dataclass(frozen=True, kw_only=True, eq=False)
class Checkpoint:
    """A checkpoint read back: the state to continue from and the results so far."""

    state: object
    """The `State` after the last step taken."""
    results: object
    """The `Results` recorded up to that step."""
    targets: RunTargets
    """The run's targets and recording options."""


def read_checkpoint(path, model) -> Checkpoint:
    """Read a checkpoint for ``model``; `ValueError` if it belongs to another model or is not a
    checkpoint."""
    from ..results import load_results

    path = Path(path)
    with _open_checkpoint(path) as data:
        meta = json.loads(str(data["checkpoint.meta"]))
        if meta.get("format") != FORMAT:
            raise ValueError(f"{path}: checkpoint format {meta.get('format')}, this ddatai reads {FORMAT}")
        if meta["model"] != model_fingerprint(model):
            raise ValueError(f"{path} was written for a different model or different parameters: a run "
                             f"resumes only with the scene and Params it started with")
        state = _state_from(data, meta["kinds"], model.initial_state())
    return Checkpoint(state=state, results=load_results(path), targets=RunTargets(**meta["targets"]))


def checkpoint_targets(path) -> RunTargets:
    """The targets and recording options stored in a checkpoint (without reading its state)."""
    path = Path(path)
    with _open_checkpoint(path) as data:
        return RunTargets(**json.loads(str(data["checkpoint.meta"]))["targets"])


def _open_checkpoint(path: Path):
    """The checkpoint's arrays (an open `np.load`); `ValueError` for a missing file or a file
    that is not a checkpoint."""
    if not path.is_file():
        raise ValueError(f"no such checkpoint: {path}")
    data = np.load(path, allow_pickle=False)
    if "checkpoint.meta" not in data.files:
        data.close()
        raise ValueError(f"{path} is not a checkpoint (results files cannot be resumed)")
    return data


class DeferInterrupt:
    """Within the block, Ctrl-C (SIGINT) is held back and raised as `KeyboardInterrupt` when
    the block ends, so what the block stores (a step's records, a checkpoint) is never left
    half-written. Does nothing outside the main thread or when SIGINT has a handler of its own."""

    def __enter__(self) -> "DeferInterrupt":
        self.hit = False
        self.previous = None
        if (threading.current_thread() is threading.main_thread()
                and signal.getsignal(signal.SIGINT) is signal.default_int_handler):
            self.previous = signal.signal(signal.SIGINT, self._hold)
        return self

    def _hold(self, signum, frame) -> None:
        self.hit = True

    def __exit__(self, exc_type, exc, tb) -> None:
        if self.previous is not None:
            signal.signal(signal.SIGINT, self.previous)
        if self.hit and exc_type is None:
            raise KeyboardInterrupt
