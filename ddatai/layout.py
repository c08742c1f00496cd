"""The contact layout: the one definition of contact states, contact kinds, the columns of the
integer contact table ``cint`` and the slots of the contact-vector array (docs/method/dda.md
§2.8, §3.5, §4.1).

The Taichi kernels (`ddatai.kernels`) use the same numbers as plain integers; a test checks
that they agree.
"""

from __future__ import annotations

from enum import IntEnum


class ContactState(IntEnum):
    """State of a contact in the open-close iteration (docs/method/dda.md §4.1)."""

    OPEN = 0
    SLIDE = 1  # normal spring + Coulomb friction loads (for vertex-vertex: normal spring only)
    LOCK = 2   # normal and shear springs


class ContactKind(IntEnum):
    VE = 0  # vertex of one block against an edge of the other (edge-edge = two of these)
    VV = 1  # vertex against vertex: two candidate entrance lines, the less penetrated one acts


OPEN, SLIDE, LOCK = int(ContactState.OPEN), int(ContactState.SLIDE), int(ContactState.LOCK)
VE, VV = int(ContactKind.VE), int(ContactKind.VV)

#: columns of the integer contact table ``cint`` (one row per contact): its kind, the contact
#: vertex and the edge it meets (line 0), and for a vertex-vertex contact the other block's
#: vertex and edge (line 1)
KIND, V0, E0, V1, E1 = range(5)

#: slots of the contact-vector array ``vec[c, slot, 0:6]``: normal gradients of line 0 for
#: blocks a and b (E0, G0), of line 1 (E1, G1), and the shear gradients (ES, GS)
S_E0, S_G0, S_E1, S_G1, S_ES, S_GS = range(6)
N_SLOTS = 6
