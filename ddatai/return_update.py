"""One return-mapping iterate's judgement of its contacts (`ddatai.return_mapping`, ``_iterate``;
docs/method/dda.md §8.12): from the contact law at the iterate's D, which contacts close, open or
change line, how far each vertex-edge contact opens by the return mapping of its normal spring,
and by how much each shear spring exceeds its strength (the slip it adds). Every term is per
contact, except each block's load level, the largest of its weight and its contacts' forces (a
maximum: exact in any order), so the members of a batch are judged side by side
(`ddatai.side_by_side`, ``ddatai.stage_batch_finish.iterate_update_many``), each its own floats.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from . import side_by_side
from .layout import KIND, VE


class Update(NamedTuple):
    """An iterate's judgement (`iterate_update`)."""

    loose: np.ndarray         # each contact's force tolerance [N/m]
    state_loose: np.ndarray   # ... and that of its state tests [N/m]
    flipped: np.ndarray       # the contacts that closed or opened
    changed: np.ndarray       # ... or changed line
    closed: np.ndarray        # the closed contacts of the next iterate
    line: np.ndarray          # their lines (int8)
    gapping: np.ndarray       # opening by the return mapping of their normal spring
    new_gap: np.ndarray       # how far each has opened so [m]
    excess: np.ndarray        # spring force beyond the strength (−inf: none) [N/m]
    dslip: np.ndarray         # the slip each adds [m]


@side_by_side.operation("iterate_update")
def iterate_update(model, contacts, law, guess, flips: np.ndarray, freeze: bool, shearing: np.ndarray,
                   weight: np.ndarray, tensile: np.ndarray, force_tolerance: float, chatter_flips: int) -> Update:
    """The judgement of an iterate (module docstring; ``_iterate`` states the rules): ``law`` the
    stage's law at D (`contact_law.stage_law`), ``guess`` the iterate's closed contacts, lines and
    gaps, ``flips`` how often each contact opened or closed, ``freeze`` whether contacts that
    flipped ``chatter_flips`` times open by the return mapping of their normal spring,
    ``shearing`` the contacts with a shear spring, ``weight`` each block's, ``tensile`` each
    contact's tensile strength [N/m], ``force_tolerance`` the stage's fraction of the load."""
    p = model.params
    pen, ks = model.penalty, model.shear_penalty
    ve = contacts.cint[:, KIND] == VE
    vv = ~ve
    # the load that each contact's blocks carry, and the force tolerance
    level = weight.copy()
    np.maximum.at(level, contacts.block_a, np.abs(law.fn))
    np.maximum.at(level, contacts.block_b, np.abs(law.fn))
    carried = np.maximum(level[contacts.block_a], level[contacts.block_b])
    loose = force_tolerance * carried + model.force_roundoff
    # normal, as the open-close judgement (`Stepper.violations`): a closed contact opens where
    # it pulls beyond its tensile strength (the strict tolerance), an open one closes where
    # it overlaps and a vertex-vertex one changes line where the other is less penetrated,
    # both where that moves a force by more than ``Params.oc_state_tolerance`` of the load
    state_loose = p.oc_state_tolerance * carried + model.force_roundoff
    closes = ~guess.closed & law.closed & (law.fn > state_loose)
    # a contact opens (K changes) — but, going on from a stall, a vertex-edge one that has
    # already opened or closed ``chatter_flips`` times opens by the return mapping of its
    # normal spring (below), K kept: states that flip back and forth do not settle
    frozen = ve & (flips >= chatter_flips) & freeze
    opens = ~frozen & guess.closed & ~law.closed & (pen * law.dn - tensile > loose)
    switch = vv & guess.closed & law.closed & (law.line != guess.line) & \
        (pen * np.abs(law.dn - law.dn_now) > state_loose)
    closed = (guess.closed | closes) & ~opens
    line = np.where(closes | switch, law.line, guess.line).astype(np.int8)
    # normal: the return mapping of the tension cut-off — a closed vertex-edge contact
    # pulled beyond its tensile strength opens by the excess (its spring's rest point moves
    # by ``gap``), and an opened one closes again as far as it is pressed (gap ≥ 0)
    allowance = tensile / pen
    gapping = frozen & closed & ((law.dn > allowance) | (guess.gap > 0.0))
    new_gap = np.where(gapping, np.maximum(guess.gap + law.dn - allowance, 0.0), 0.0)
    normal_excess = pen * np.abs(new_gap - guess.gap)
    # shear: the return mapping
    trial = ks * law.ds
    excess = np.where(shearing & closed, np.abs(trial) - law.strength, -np.inf)
    excess = np.maximum(excess, np.where(gapping, normal_excess, -np.inf))
    dslip = np.where(excess > 0, np.maximum(np.abs(trial) - law.strength, 0.0) / ks * np.sign(trial), 0.0)
    dslip = np.where(shearing & closed, dslip, 0.0)
    return Update(loose=loose, state_loose=state_loose, flipped=closes | opens, changed=closes | opens | switch,
                  closed=closed, line=line, gapping=gapping, new_gap=new_gap, excess=excess, dslip=dslip)
