"""The Recorder's step records: a step at a time (today's path) and a launch's rows at once (the
fused engine) kept in the order they came (`ddatai.recorder.Recorder.step_rows`)."""

import numpy as np

from ddatai.records import STEP_DTYPE
from ddatai.recorder import Recorder


def _rows(first: int, n: int) -> np.ndarray:
    rows = np.zeros(n, STEP_DTYPE)
    rows["time"] = 1e-3 * np.arange(first, first + n)
    rows["oc_total"] = np.arange(n) + 1
    return rows


def test_step_records_keep_their_order_across_launches_and_single_steps():
    rec = Recorder(model=None, record_contacts=False)
    assert len(rec.step_records()) == 0 and rec.step_records().dtype == STEP_DTYPE
    rec.steps.extend(tuple(r) for r in _rows(1, 2))     # today's path, a step at a time
    rec.step_rows(_rows(3, 4))                           # a launch of the fused engine
    launch = _rows(7, 3)
    rec.step_rows(launch)
    launch["time"] = -1.0                                 # the engine reuses its buffers
    rec.steps.append(tuple(_rows(10, 1)[0]))            # handed over to today's path
    out = rec.step_records()
    assert out.dtype == STEP_DTYPE
    np.testing.assert_array_equal(out["time"], 1e-3 * np.arange(1, 11))
    # the same records as the tuple a step that the fused engine's rows were handed over as before
    before = np.array([tuple(r) for r in np.concatenate([_rows(1, 2), _rows(3, 4), _rows(7, 3), _rows(10, 1)])],
                      dtype=STEP_DTYPE)
    assert out.tobytes() == before.tobytes()
