"""Contacts: detection (Taichi kernels), memory transfer between steps, sparse block pattern.

`detect_contacts` runs the broad phase (hashed uniform grid, plus an all-against-one test for
the few boxes larger than a cell) and Shi's narrow phase, then sorts the contacts so that runs
are reproducible whatever the thread scheduling. `Contacts.start` attaches joint properties and
the memory of the previous step (docs/method/dda.md §3.7). `BlockPattern` is the CSR layout of the
global matrix for one step: one dense 6×6 block per free block and per contacting pair.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

# the states and kinds as plain ints: a NumPy comparison with an IntEnum member costs ~5× one with
# an int (the member is converted on every call)
from . import side_by_side
from .layout import E0, E1, KIND, LOCK, OPEN, SLIDE, V0, V1, VE
from .model import ContactMemory, Model


def box_bounds(model: Model, vertex_xy: np.ndarray, margin: float) -> tuple[np.ndarray, np.ndarray]:
    """Axis-aligned bounding boxes of all blocks, enlarged by ``margin`` on every side."""
    starts = model.vertex_offset[:-1]
    lo = np.minimum.reduceat(vertex_xy, starts, axis=0) - margin
    hi = np.maximum.reduceat(vertex_xy, starts, axis=0) + margin
    return lo, hi


#: the broad phase finds the block pairs within the search distance plus a skin of this many
#: search distances, and the pairs serve later detections while no vertex has moved half the
#: skin (a Verlet list: two blocks that close the skin in between must have moved that far)
PAIR_SKIN = 1.0


class PairList:
    """The candidate block pairs of the last broad phase, found with a skin of `PAIR_SKIN`
    search distances, and the vertex positions and search distance they were found at (a Verlet
    list, `pairs`)."""

    def __init__(self):
        self.found = None       # (P, 2) the pairs
        self.found_at = None    # (V, 2) the vertex positions they were found at [m]
        self.margin = 0.0       # the search distance they serve [m]

    def pairs(self, model: Model, vertex_xy: np.ndarray, broad) -> np.ndarray:
        """The block pairs that may touch within the search distance: those of
        ``broad(model, vertex_xy, margin)`` (a broad phase, `broad_phase` or its NumPy twin)
        found with the skin, kept while every vertex is within half of it of where they were
        found. Every pair whose boxes are within the search distance now is among them, and
        the narrow phase, pair by pair, finds the same contacts as after a fresh broad phase
        (tests/test_contacts.py)."""
        d = model.search_distance
        skin = PAIR_SKIN * d
        at = self.found_at
        if at is not None and at.shape == vertex_xy.shape and self.margin == d:
            dx = vertex_xy - at
            if float(np.max(dx[:, 0] * dx[:, 0] + dx[:, 1] * dx[:, 1], initial=0.0)) < 0.25 * skin * skin:
                return self.found
        self.found = broad(model, vertex_xy, d + skin)
        self.found_at, self.margin = vertex_xy.copy(), d
        return self.found


class _Buffers:
    """Output buffers reused between steps; grown (doubled) when a kernel reports overflow; the
    candidate pairs kept between detections (`PairList`)."""

    def __init__(self):
        self.pairs = np.zeros((64, 2), np.int32)
        self.cint = np.zeros((256, 5), np.int32)
        self.clen = np.zeros(256)
        self.count = np.zeros(1, np.int32)
        self.pair_list = PairList()
        self.no_memory = np.zeros((1, 3), np.int32)  # a kernel takes no empty array


def broad_phase(model: Model, vertex_xy: np.ndarray, margin: float, buffers: _Buffers) -> np.ndarray:
    """Candidate block pairs (i < j, not both fixed) whose boxes, enlarged by margin/2, overlap.

    Returns a (P, 2) int32 array sorted by (i, j).
    """
    from . import kernels as K

    lo, hi = box_bounds(model, vertex_xy, 0.5 * margin)
    nb = len(lo)
    if nb < 2:
        return np.zeros((0, 2), np.int32)
    ext = (hi - lo).max(axis=1)
    # cell size: the largest box that is not "big" (more than 4× the median size); the few
    # big boxes (typically a fixed base) are tested against all others instead of binned
    med = float(np.median(ext))
    big = ext > 4.0 * med
    h = float(ext[~big].max())
    big_i = big.astype(np.int32)
    fixed = model.block_fixed.astype(np.int32)
    table = max(64, 2 * nb)
    ox, oy = lo.min(axis=0)
    sorted_ids = np.zeros(max(1, int(np.count_nonzero(~big))), np.int32)
    big_ids = np.flatnonzero(big).astype(np.int32)
    n_big = len(big_ids)
    if not n_big:
        big_ids = np.zeros(1, np.int32)  # a kernel takes no empty array
    cell = np.zeros((nb, 2), np.int32)
    bucket = np.zeros(nb, np.int32)
    while True:
        bucket_count = np.zeros(table, np.int32)
        bucket_start = np.zeros(table + 1, np.int32)
        buffers.count[0] = 0
        K.broad_pairs(lo, hi, big_i, h, float(ox), float(oy), table, cell, bucket, bucket_count, bucket_start,
                      np.zeros(table, np.int32), sorted_ids, big_ids, n_big, fixed, buffers.pairs, buffers.count)
        n = int(buffers.count[0])
        if n <= len(buffers.pairs):
            break
        buffers.pairs = np.zeros((2 * n, 2), np.int32)
    pairs = buffers.pairs[:n]
    order = np.lexsort((pairs[:, 1], pairs[:, 0]))
    return pairs[order].copy()


def memory_rows(last_keys: np.ndarray, n_vertices: int) -> np.ndarray:
    """The vertex-edge contacts among the sorted keys of the last step's contacts
    (`contact_keys`, ``ContactMemory.key``) as rows (kind 0, vertex, edge) in the same order:
    the memory the narrow-phase kernel searches (``kernels.common.MEM_KIND`` …), as the fused
    engine's members search theirs."""
    n = np.int64(n_vertices)
    keys = last_keys[:np.searchsorted(last_keys, n * n)]  # the vertex-edge keys come first
    rows = np.zeros((len(keys), 3), np.int32)
    rows[:, 1], rows[:, 2] = keys // n, keys % n
    return rows


def narrow_phase(model: Model, vertex_xy: np.ndarray, pairs: np.ndarray, buffers: _Buffers,
                 last_keys: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Contacts of the candidate pairs: (cint (m, 5) int32, length (m,)), sorted. ``last_keys``:
    the sorted keys of the last step's contacts, which keep a corner pair's hand-over to the
    vertex-edge rules (docs/method/dda.md §3.4; ``ddatai.narrow.narrow_phase``)."""
    from . import kernels as K

    p = model.params
    if len(pairs) == 0:
        return np.zeros((0, 5), np.int32), np.zeros(0)
    mem = memory_rows(np.asarray(last_keys), model.n_vertices) if last_keys is not None else buffers.no_memory[:0]
    n_mem = len(mem)
    if not n_mem:
        mem = buffers.no_memory
    while True:
        buffers.count[0] = 0
        K.narrow_phase(pairs, vertex_xy, model.vertex_offset, model.vertex_next, model.vertex_prev,
                       model.search_distance, model.max_penetration, np.radians(p.angle_tolerance),
                       mem, n_mem, buffers.cint, buffers.clen, buffers.count)
        n = int(buffers.count[0])
        if n <= len(buffers.cint):
            break
        buffers.cint = np.zeros((2 * n, 5), np.int32)
        buffers.clen = np.zeros(2 * n)
    return sort_contacts(buffers.cint[:n].copy(), buffers.clen[:n].copy())


def sort_contacts(cint: np.ndarray, length: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Canonical order (by kind, vertex0, edge0, vertex1, edge1): makes runs reproducible."""
    order = np.lexsort((cint[:, 4], cint[:, 3], cint[:, 2], cint[:, 1], cint[:, 0]))
    return cint[order], length[order]


def detect_contacts(model: Model, vertex_xy: np.ndarray, buffers: _Buffers | None = None,
                    last_keys: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Broad + narrow phase on the Taichi backend. Returns (cint, length) in canonical order.
    ``last_keys``: the sorted keys of the last step's contacts (``ContactMemory.key``), as
    ``ddatai.vectorized.detect_contacts``."""
    buffers = buffers or _Buffers()
    pairs = buffers.pair_list.pairs(model, vertex_xy, lambda m, xy, margin: broad_phase(m, xy, margin, buffers))
    return narrow_phase(model, vertex_xy, pairs, buffers, last_keys)


def contact_keys(cint: np.ndarray, n_vertices: int) -> np.ndarray:
    """Identity of each contact for the transfer between steps: (vertex, edge) for a
    vertex-edge contact, (vertex, vertex) for a vertex-vertex contact."""
    v = np.int64(n_vertices)
    k = cint[:, V0].astype(np.int64) * v
    ve = cint[:, KIND] == VE
    return np.where(ve, k + cint[:, E0], v * v + k + cint[:, V1])


#: the fields of `Contacts` fixed during a step (its contacts' identity and geometry): never written in place
GEOMETRY = frozenset({"cint", "length", "key", "block_a", "block_b", "joint"})


@dataclass(kw_only=True, eq=False)
class Contacts:
    """The contacts of one step: geometry (fixed during the step) and open-close state.

    m contacts; a vertex-vertex contact has two entrance lines (``line`` says which acts).
    """

    cint: np.ndarray
    """(m, 5) int32 (kind, vertex0, edge0, vertex1, edge1); line 1 only for vertex-vertex."""
    length: np.ndarray
    """(m,) contact length L of an edge-edge contact (half the overlap), else 0 [m]."""
    key: np.ndarray
    """(m,) int64 identity (see `contact_keys`)."""
    block_a: np.ndarray
    """(m,) block of vertex0."""
    block_b: np.ndarray
    """(m,) block of edge0."""
    tan_phi: np.ndarray
    """(m,) tan of the friction angle; on a Barton–Bandis joint the secant tan φ(σn) at the
    contact's normal stress of the last solve (`barton_tan`), updated by the open-close
    judgement."""
    joint: np.ndarray
    """(m,) int32 joint-table index of each contact."""
    slip: np.ndarray
    """(m,) shear displacement slid so far [m], for softening Barton–Bandis joints (zeros
    otherwise, and never updated)."""
    friction_deg: np.ndarray
    """(m,) friction angle [degrees]."""
    cohesion: np.ndarray
    """(m,) cohesion [Pa]."""
    tensile: np.ndarray
    """(m,) tensile strength [Pa]."""
    state: np.ndarray
    """(m,) int8 `ContactState` assumed for the next solve."""
    line: np.ndarray
    """(m,) int8 active line (0 or 1)."""
    omega: np.ndarray
    """(m,) lock position on the reference edge."""
    bond: np.ndarray
    """(m,) bool joint intact."""
    shear_dir: np.ndarray
    """(m,) int8 direction of sliding (+1/-1; friction acts against it)."""
    dn: np.ndarray
    """(m,) normal distance of the active line from the last solve (start: dn0) [m]."""
    ds: np.ndarray
    """(m,) shear displacement from the last solve [m]."""
    normal_force: np.ndarray
    """(m,) compressive normal force p·(−dn) of the contact from the last solve in which it was
    closed (the end of the last step, or the start penetration) [N/m]. Sets the friction of a
    sliding contact that is not `coupled`. An open contact's penetration is unresisted
    overshoot, and p times it is no contact force."""
    coupled: np.ndarray
    """(m,) bool: the friction of this sliding contact follows the normal force of the same
    solve (implicit friction, a non-symmetric term in K) instead of ``normal_force``."""

    @property
    def n(self) -> int:
        return len(self.key)

    def copy(self) -> "Contacts":
        """A copy whose state can change apart; the geometry (``GEOMETRY``, fixed during the step and
        written by no one) is shared: the batched evaluations know it again (`ddatai.stage_batch_index`)."""
        return Contacts(**{k: (v.copy() if isinstance(v, np.ndarray) and k not in GEOMETRY else v)
                           for k, v in vars(self).items()})

    @staticmethod
    @side_by_side.operation("contacts_start")
    def start(model: Model, vertex_xy: np.ndarray, cint: np.ndarray, length: np.ndarray,
              memory: ContactMemory, first_step: bool) -> "Contacts":
        """Attach joint properties and last step's memory to freshly detected contacts.

        Transferred (same vertex and reference edge): state, active line, bond, sliding
        direction, normal force (of a closed contact); the lock position ω only if the contact
        was locked. Others are re-anchored
        at the projection of the vertex, so their shear displacement restarts at 0 — except
        sliding contacts, anchored so that a lock would start with their friction force.
        New contacts start open, except on the first step, where contacts touching within the
        opening tolerance start closed and locked (vertex-edge), and edge-edge contacts of the
        initial geometry are bonded (docs/method/dda.md §3.7, §2.8.5).

        Its twin for many members at once, ``ddatai.stage_batch_contacts.contacts_start_many``,
        writes these rules again over a member axis; tests/test_stage_batch_more.py holds the two
        equal to the bit, so a change here fails there until the twin follows.
        """
        m = len(cint)
        key = contact_keys(cint, model.n_vertices)
        a = model.vertex_block[cint[:, V0]]
        b = model.vertex_block[cint[:, E0]]
        joint = model.edge_joint[cint[:, E0]].copy()
        if len(model.pair_key):
            nb = np.int64(model.n_blocks)
            pk = np.minimum(a, b).astype(np.int64) * nb + np.maximum(a, b)
            pos = np.minimum(np.searchsorted(model.pair_key, pk), len(model.pair_key) - 1)
            hit = model.pair_key[pos] == pk
            joint[hit] = model.pair_joint[pos[hit]]
        kind = cint[:, KIND]
        ve = kind == VE
        dn0 = signed_distance(vertex_xy, model.vertex_next, cint[:, V0], cint[:, E0])
        state = np.zeros(m, np.int8)
        line = np.zeros(m, np.int8)
        bond = np.zeros(m, bool)
        shear_dir = np.ones(m, np.int8)
        omega = edge_projection(vertex_xy, model.vertex_next, cint[:, V0], cint[:, E0])
        # a VV contact acts on one of its two lines: a new one starts on the less penetrated
        # (§2.8.7), and the start penetration that sets its normal force is that line's, never
        # that of a line it does not use (a corner 0.75 mm past the other's edge is no 1e7 N/m)
        vv = ~ve
        dn1 = np.full(m, -np.inf)
        if np.count_nonzero(vv):
            dn1[vv] = signed_distance(vertex_xy, model.vertex_next, cint[vv, V1], cint[vv, E1])
        line[vv] = dn1[vv] > dn0[vv]
        normal_force = model.penalty * np.maximum(-np.where(line == 1, dn1, dn0), 0.0)
        tan_phi = model.joint_tan_phi[joint]
        if len(memory.key) and m:
            pos = np.minimum(np.searchsorted(memory.key, key), len(memory.key) - 1)
            found = memory.key[pos] == key
            src = pos[found]
            state[found] = memory.state[src]
            line[found] = memory.line[src]
            normal_force[found & vv] = model.penalty * np.maximum(-np.where(line == 1, dn1, dn0)[found & vv], 0.0)
            bond[found] = memory.bond[src]
            shear_dir[found] = memory.shear_dir[src]
            closed = found.copy()
            closed[found] = memory.state[src] != OPEN
            normal_force[closed] = memory.normal_force[pos[closed]]
        slip = np.zeros(m)
        if len(memory.slip) and m:
            slip[found] = memory.slip[src]
        if len(model.joint_barton) and m:
            # Barton–Bandis joints: friction at each contact's normal stress (eq. BB1–BB2)
            bb = np.flatnonzero(~np.isnan(model.joint_barton[joint, 0]))
            tan_phi[bb] = barton_tan(model, joint[bb], normal_force[bb], length[bb], slip[bb])
        if len(memory.key) and m:
            locked = found.copy()
            locked[found] = memory.state[src] == LOCK
            omega[locked] = memory.omega[pos[locked]]
            sliding = found & (state == SLIDE) & ve
            if np.count_nonzero(sliding):
                # A sliding contact carries the friction force S opposite to its sliding
                # direction. Its lock point is placed S/ks behind the vertex, so that if it
                # locks again its shear spring starts from that same force: no force jump at the
                # slide -> lock transition, hence no endless stick-slip chatter at exactly
                # mobilised friction (Shi re-anchors at zero force).
                joint_s = joint[sliding]
                length_s = length[sliding]
                strength = normal_force[sliding] * tan_phi[sliding] + \
                    model.joint_cohesion[joint_s] * length_s * bond[sliding]
                edge_len = np.linalg.norm(vertex_xy[cint[sliding, E0]] -
                                          vertex_xy[model.vertex_next[cint[sliding, E0]]], axis=1)
                omega[sliding] -= shear_dir[sliding] * strength / (model.shear_penalty * edge_len)
        if first_step and m:
            # contacts the equilibrium stage left in memory keep their state; the others start
            # closed where they touch
            new = np.ones(m, bool) if not len(memory.key) else ~found
            touching = (np.maximum(dn0, dn1) <= model.open_tol) & new
            state[touching & ve] = LOCK
            state[touching & vv] = SLIDE
            bond[touching & ve & (length > 0)] = True
        return Contacts(
            cint=cint, length=length, key=key, block_a=a, block_b=b,
            tan_phi=tan_phi, joint=joint.astype(np.int32), slip=slip, friction_deg=model.joint_friction[joint],
            cohesion=model.joint_cohesion[joint], tensile=model.joint_tensile[joint],
            state=state, line=line, omega=omega, bond=bond, shear_dir=shear_dir,
            dn=dn0, ds=np.zeros(m), normal_force=normal_force,
            coupled=(state == SLIDE) & ve & (tan_phi > 0))

    def memory(self, bond_breaks_on_slip: bool = True) -> ContactMemory:
        """What this step hands to the next. The bond survives on locked contacts, and also on
        sliding ones when ``bond_breaks_on_slip`` is False (`Params.bond_breaks_on_slip`)."""
        locked = self.state == LOCK
        if not bond_breaks_on_slip:  # "locked" then means: keeps its bond
            locked = locked | (self.state == SLIDE)
        return ContactMemory(key=self.key.copy(), state=self.state.copy(), line=self.line.copy(),
                             omega=self.omega.copy(), bond=self.bond & locked,
                             shear_dir=self.shear_dir.copy(), dn=self.dn.copy(),
                             normal_force=self.normal_force.copy(), kind=self.cint[:, KIND].astype(np.int8),
                             slip=self.slip.copy() if np.count_nonzero(self.slip) else np.zeros(0))


def barton_tan(model: Model, joint: np.ndarray, normal_force: np.ndarray, length: np.ndarray,
               slip: Optional[np.ndarray] = None) -> np.ndarray:
    """Secant friction coefficient tan φ(σn)/F of contacts on Barton–Bandis joints
    (docs/method/barton_bandis.md): σn = N/L, the contact's normal force over its length
    (eq. BB2; a corner contact, L = 0, has σn = ∞), φ(σn) = φr + JRC·log10(JCS/σn) bounded to
    [φr, cap] (eq. BB1; σn ≤ 0, an unloaded contact, takes the cap). A softening joint's JRC
    is that mobilised after the contact's ``slip`` (eq. BB7)."""
    jrc, jcs, phir, cap, red, peak = model.joint_barton[joint].T
    soft = ~np.isnan(peak)
    if slip is not None and np.count_nonzero(soft):
        from .params import jrc_mobilised

        jrc = jrc.copy()
        jrc[soft] *= jrc_mobilised(slip[soft], peak[soft])
    n = np.maximum(normal_force, 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        sigma = np.where(length > 0, n / np.where(length > 0, length, 1.0), np.where(n > 0, np.inf, 0.0))
        phi = phir + jrc * np.log10(jcs / sigma)
    phi = np.where(sigma > 0, np.clip(phi, phir, cap), np.where(jrc > 0, cap, phir))  # σn → 0: the limit
    return np.tan(np.radians(phi)) / red


def signed_distance(xy: np.ndarray, vnext: np.ndarray, vertex: np.ndarray, edge: np.ndarray) -> np.ndarray:
    """Signed distance of vertices from the lines of edges (positive outside the edge's block)."""
    q0 = xy[edge]
    d = xy[vnext[edge]] - q0
    r = xy[vertex] - q0
    return (r[:, 0] * d[:, 1] - r[:, 1] * d[:, 0]) / np.hypot(d[:, 0], d[:, 1])


def edge_projection(xy: np.ndarray, vnext: np.ndarray, vertex: np.ndarray, edge: np.ndarray) -> np.ndarray:
    """ω of the projection of each vertex on its reference line P2 -> P3 (P2 = edge end)."""
    p2 = xy[vnext[edge]]
    d = xy[edge] - p2
    return ((xy[vertex] - p2) * d).sum(axis=1) / (d * d).sum(axis=1)


def subset_contacts(contacts: Contacts, keep: np.ndarray) -> Contacts:
    """The contacts where ``keep``."""
    return Contacts(**{k: v[keep] for k, v in vars(contacts).items()})


def coupled(contacts: Contacts) -> Contacts:
    """A copy whose friction follows the normal force of the solve it is evaluated at."""
    c = contacts.copy()
    c.coupled[:] = True
    return c
