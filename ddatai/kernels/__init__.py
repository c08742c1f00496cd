"""Taichi kernels of the step: broad phase, narrow phase (Shi's contact rules), contact vectors,
assembly, and the contact law.

Importing this package imports Taichi (it is loaded only when a simulation runs); kernels
compile on first call after `ddatai.backend.ensure`. Every kernel works on NumPy arrays
passed as ``ti.types.ndarray`` (no copies on the CPU backend) and has a plain NumPy twin in
:mod:`ddatai.reference`, ``ddatai.narrow``, :mod:`ddatai.assembly` or
:mod:`ddatai.contact_law`; tests compare the two.

One module a concern: `ddatai.kernels.common` (argument types, the contact layout as plain
integers, guards and vector helpers), `ddatai.kernels.broad` (the broad phase),
`ddatai.kernels.detection` (the narrow phase), `ddatai.kernels.assembly` (contact vectors and
the assembly of K and F) and `ddatai.kernels.law` (the contact law and the open-close
judgement). The names below are those the step's modules use.
"""

from .assembly import assemble_blocks, assemble_contact_loads, assemble_contacts, assemble_points, contact_vectors, second_order_shift
from .broad import big_query, broad_pairs, grid_bin, grid_query, grid_scatter
from .common import (E0, E1, EDGE_FLOOR, EDGE_FLOOR2, ES, G0, G1, GS, IN_BOND, IN_COHESION, IN_COUPLED,
                     IN_LENGTH, IN_LINE, IN_NORMAL_FORCE, IN_SHEAR_DIR, IN_STATE, IN_TAN_PHI, IN_TENSILE,
                     KIND_VE, KIND_VV, LAW_CLOSED, LAW_DIRECTION, LAW_DN, LAW_DN_NOW, LAW_DS, LAW_ENERGY,
                     LAW_FN, LAW_FN_NOW, LAW_FRICTION_NOW, LAW_FT, LAW_FT_NOW, LAW_LINE, LAW_STATE,
                     LAW_STRENGTH, N_SLOTS, PASSED_DEPTH, SLACK, STATE_LOCK, STATE_OPEN, STATE_SLIDE, TIE, TWO_PI)
from .detection import narrow_phase
from .law import contact_law, internal_force, violations

__all__ = [
    "assemble_blocks", "assemble_contact_loads", "assemble_contacts", "assemble_points", "big_query", "broad_pairs", "contact_law", "contact_vectors",
    "grid_bin", "grid_query", "grid_scatter", "internal_force", "narrow_phase", "second_order_shift",
    "violations",
    "E0", "E1", "EDGE_FLOOR", "EDGE_FLOOR2", "ES", "G0", "G1", "GS", "IN_BOND", "IN_COHESION", "IN_COUPLED",
    "IN_LENGTH", "IN_LINE", "IN_NORMAL_FORCE", "IN_SHEAR_DIR", "IN_STATE", "IN_TAN_PHI", "IN_TENSILE",
    "KIND_VE", "KIND_VV", "LAW_CLOSED", "LAW_DIRECTION", "LAW_DN", "LAW_DN_NOW", "LAW_DS", "LAW_ENERGY",
    "LAW_FN", "LAW_FN_NOW", "LAW_FRICTION_NOW", "LAW_FT", "LAW_FT_NOW", "LAW_LINE", "LAW_STATE",
    "LAW_STRENGTH", "N_SLOTS", "PASSED_DEPTH", "SLACK", "STATE_LOCK", "STATE_OPEN", "STATE_SLIDE", "TIE", "TWO_PI",
]
