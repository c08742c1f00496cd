"""Shared pieces of the Taichi kernels: argument types, the contact layout as plain integers
(a ``@ti.func`` cannot read an enum; `ddatai.layout` has the one definition and
tests/test_layout.py checks these equal it), the narrow phase's guards, and small vector helpers.

Conventions (see :mod:`ddatai.model`): block b owns vertices ``voff[b]:voff[b+1]`` in CCW
order, edge k runs from vertex k to ``vnext[k]``. A vertex-edge contact of vertex P1 against
edge k uses the reference line P2 = vnext[k] -> P3 = k, which runs clockwise around the edge's
block, so that the signed normal distance is positive outside (docs/method/dda.md §2.8.1, §3.5).

Contact vectors are stored per contact c in ``vec[c, s, 0:6]`` with slots
``E0, G0`` (normal, line 0), ``E1, G1`` (normal, line 1 of a vertex-vertex contact) and
``ES, GS`` (shear, line 0: the gradient of ds, along which both the shear spring and the
friction force act), and the constant parts in ``sca[c, 0:3]`` = (dn0 line 0, dn0 line 1, ds0);
see docs/method/dda.md §2.8.
"""

import math

import taichi as ti

F64_1 = ti.types.ndarray(dtype=ti.f64, ndim=1)
F64_2 = ti.types.ndarray(dtype=ti.f64, ndim=2)
F64_3 = ti.types.ndarray(dtype=ti.f64, ndim=3)
I32_1 = ti.types.ndarray(dtype=ti.i32, ndim=1)
I32_2 = ti.types.ndarray(dtype=ti.i32, ndim=2)
I8_1 = ti.types.ndarray(dtype=ti.i8, ndim=1)
I8_2 = ti.types.ndarray(dtype=ti.i8, ndim=2)

KIND_VE = 0
KIND_VV = 1
STATE_OPEN = 0
STATE_SLIDE = 1
STATE_LOCK = 2
# slots of the contact vector array
E0, G0, E1, G1, ES, GS = 0, 1, 2, 3, 4, 5
N_SLOTS = 6
TWO_PI = 2.0 * math.pi
#: guards of the narrow phase: an edge this short (or its square) is collapsed — it gets no
#: contact and divides by this instead of 0 (input checks make every edge ≥ 1e-12 of the block)
EDGE_FLOOR = 1e-150
EDGE_FLOOR2 = EDGE_FLOOR * EDGE_FLOOR
#: When the corners of two parallel edges (nearly) coincide, either corner can be the contact
#: vertex; block A's is kept unless B's lies clearly (TIE × edge length) further inside the
#: other edge. Without this the choice follows round-off and the contact's identity, and with
#: it its memory, changes from step to step (aligned grids: every X-junction).
TIE = 1e-3

#: round-off slack of the shortest-exit rule (§3.3 rule 3): of d9 for a vertex on an edge's
#: line, of the edge for its projection (a cut's shared vertex lies on its neighbours' lines
#: and at their ends, to round-off)
SLACK = 1e-9

#: a vertex of a vertex pair that has passed its partner's corner along one of its edges (the
#: corners of diagonal blocks where four squares meet, once a row slides) and lies deeper than
#: this share of d9 behind that edge goes, with its partner, to the vertex-edge rules
#: (docs/method/dda.md §3.4): beyond the elastic settlement of such corners at rest
#: (1e-11–1e-10 m of d9 = 3.75 mm in a stack of 0.1 m squares), far short of a depth whose
#: push-out in one step throws a block (36 µm threw a square at 30 g·Δt)
PASSED_DEPTH = 1e-6

#: columns of a row of the last step's contact memory that the narrow phase reads (kind, vertex0,
#: edge0 or vertex1: a contact's identity, ``ddatai.contacts.contact_keys``), rows sorted by them:
#: the kernel path's (``ddatai.contacts.memory_rows``) and the fused engine's ``memi``
#: (`ddatai.fused.layout`, whose first columns these are)
MEM_KIND, MEM_V0, MEM_K2 = 0, 1, 2

# columns of the contact-law kernel's outputs (`ddatai.contact_law.ContactLaw` fields)
LAW_DN, LAW_DS, LAW_FN, LAW_FT, LAW_STRENGTH, LAW_DN_NOW, LAW_FN_NOW, LAW_FT_NOW, LAW_FRICTION_NOW, \
    LAW_ENERGY = range(10)
LAW_LINE, LAW_CLOSED, LAW_STATE, LAW_DIRECTION = range(4)
# columns of its per-contact inputs
IN_STATE, IN_LINE, IN_COUPLED, IN_BOND, IN_SHEAR_DIR = range(5)
IN_TAN_PHI, IN_COHESION, IN_TENSILE, IN_LENGTH, IN_NORMAL_FORCE = range(5)


# --------------------------------------------------------------------------- helpers
@ti.func
def _pt(xy: ti.template(), i):
    return ti.Vector([xy[i, 0], xy[i, 1]])


@ti.func
def _cross(a, b):
    return a[0] * b[1] - a[1] * b[0]


@ti.func
def _dot2(a, b):
    """a·b of 2-vectors, written out: the same sum as ``a.dot(b)`` (whose generic reduction costs
    Taichi several times the work to compile, ~60 uses in the narrow phase and the fused engine)."""
    return a[0] * b[0] + a[1] * b[1]


@ti.func
def _norm2(a):
    """|a| of a 2-vector, as ``a.norm()``."""
    return ti.sqrt(a[0] * a[0] + a[1] * a[1])


@ti.func
def _wrap(angle, lower):
    """angle wrapped into [lower, lower + 2π)."""
    return angle - TWO_PI * ti.floor((angle - lower) / TWO_PI)


@ti.func
def _trow(a, b, X):
    """a·T(X)row1 + b·T(X)row2 as a 6-vector (T of docs/method/dda.md §1.1, X centroidal)."""
    return ti.Vector([a, b, -a * X[1] + b * X[0], a * X[0], b * X[1], 0.5 * (a * X[1] + b * X[0])])


@ti.func
def _store(vec: ti.template(), c, slot, v):
    for a in ti.static(range(6)):
        vec[c, slot, a] = v[a]



@ti.func
def _dot6(vec: ti.template(), c, s, d: ti.template(), b):
    acc = 0.0
    for a in ti.static(range(6)):
        acc += vec[c, s, a] * d[b, a]
    return acc


@ti.func
def _box(xy: ti.template(), lo, hi):
    """The bounding box (lower, upper corner) of vertices ``lo:hi``."""
    low = ti.Vector([1e300, 1e300])
    high = ti.Vector([-1e300, -1e300])
    for k in range(lo, hi):
        low = ti.min(low, _pt(xy, k))
        high = ti.max(high, _pt(xy, k))
    return low, high


@ti.func
def _beyond(P, low, high, reach):
    """Whether P lies farther than ``reach`` outside the box (low, high) along an axis."""
    return P[0] < low[0] - reach or P[0] > high[0] + reach or P[1] < low[1] - reach or P[1] > high[1] + reach
