"""Detection shared by the members of a batch (docs/method/dda.md §8.12): the members of a kgm
batch — the samples of a probabilistic study, the probes of a bisection round — are one group
on one geometry at different joint strengths, so each member's first detection, at t = 0 (its
screen's and its first pseudo-step's, `ddatai.start`), finds the same contacts. It is done once
for the members whose detection reads the same data (``detection_key``: every field of the
model and of the state that the NumPy broad and narrow phases read), and handed to the others
with the candidate pairs and their topology (`ddatai.step.Stepper.adopt_detection`): each
member's detections then give, to the bit, what its own would have given.
"""

from __future__ import annotations

import numpy as np

from .memo import key


def detection_key(model, vertex_xy: np.ndarray):
    """The data that a NumPy detection of ``model`` at ``vertex_xy`` reads
    (`ddatai.vectorized.detect_contacts`: the vertex lists and positions, which blocks are fixed,
    the search distance, the penetration limit and the angle tolerance), as bytes; None for a
    model detected by the kernels (nothing is shared). The last step's contact keys, which the
    narrow phase reads too, are the caller's: an adopted detection answers only a call with the
    same ones (`ddatai.step.Stepper.detect`)."""
    if not model.numpy_path:
        return None
    arrays = (vertex_xy, model.vertex_next, model.vertex_prev, model.vertex_block, model.vertex_offset,
              model.block_fixed)
    return key(*(np.asarray(x) for x in arrays), float(model.search_distance), float(model.max_penetration),
               float(model.params.angle_tolerance))


def share_detection(steppers, states) -> int:
    """Detect once for each set of members (``steppers[k]`` at ``states[k]``) with one
    `detection_key`, the others adopting that detection. Returns how many adopted it."""
    first: dict = {}
    shared = 0
    for stepper, state in zip(steppers, states):
        k = detection_key(stepper.model, state.vertex_xy)
        if k is None:
            continue
        if k not in first:
            stepper.detect(state.vertex_xy)
            first[k] = stepper
        else:
            stepper.adopt_detection(first[k])
            shared += 1
    return shared
