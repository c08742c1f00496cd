"""Members of a fused launch as the engine's flat arrays, and back (NumPy only, no Taichi).

``pack`` lays the members' models and states side by side in the global arrays of
`ddatai.fused.layout` (each member in its own coordinates: members share no space, only
arrays), with a contact region of fixed capacity each; ``unpack_state`` returns a member's
`ddatai.model.State` (its contact memory keyed as today's path keys it), so that a member can go
on anywhere: in a new launch with more room, or on today's path. ``covers`` says whether the
engine runs a model, and why not.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional

import numpy as np

from . import layout as L

#: a member's contact region holds at least this many contacts ...
MIN_CONTACTS = 32
#: ... or this many per vertex of its model, or twice its memory, whichever is more
CONTACTS_PER_VERTEX = 2


@dataclass(kw_only=True, eq=False)
class Member:
    """One run of the fused engine: a model from a state, until its end, with what it records."""

    model: object
    """The member's `ddatai.model.Model` (its penalty raised where the run raised it)."""
    state: object
    """The `ddatai.model.State` it starts (or goes on) from."""
    t_end: float = math.inf
    """Simulated time to reach [s] (the last step shortened to end on it); inf: none."""
    step_end: int = -1
    """Step count to reach (the state's ``step`` counts); -1: none."""
    stop_at: float = math.inf
    """Stop once the largest displacement of ``group`` passes this [m] (`STOP_MOVED`)."""
    rest_limit: float = -1.0
    """Stop once every free block has been slower than this [m/s] for ``rest_steps`` steps
    (`STOP_REST`); negative: never."""
    rest_steps: int = 0
    group: tuple = ()
    """Blocks (of the model) whose displacement is recorded every step and stopped on."""
    record: bool = False
    """Keep a step record (``ddatai.records.STEP_DTYPE``) of every step."""
    frame_every: int = 0
    """Keep a frame every this many steps (counted by the state's ``step``) and at the end; 0:
    none."""
    start_penalty: Optional[float] = None
    """The penalty the run started with (the automatic penalty is raised at most 100 × it); None:
    the model's."""
    quiet: int = 0
    """Steps at rest so far (`rest_limit`)."""
    contacts: int = 0
    """Capacity of its contact region (0: chosen from the model)."""


def covers(model) -> Optional[str]:
    """Why the fused engine does not run ``model`` (a sentence), or None if it does: gravity,
    Mohr–Coulomb joints with cohesion and tension, fixed blocks and points, constant point loads
    and measured points. Water, bolts, Barton–Bandis joints, ground shaking and loads that vary
    in time run on today's paths."""
    if model.ground_acceleration is not None:
        return "the model is shaken (ground acceleration): the fused engine has no time functions"
    if any(callable(f) for f in model.load_force):
        return "a point load varies in time: the fused engine has no time functions"
    if len(model.joint_barton):
        return "the model has Barton–Bandis joints"
    if model.water_unit_weight > 0:
        return "the model has water pressure"
    if len(model.bolt_block):
        return "the model has rock bolts"
    return None


def row_order(model, xy: np.ndarray) -> np.ndarray:
    """The free blocks in an envelope-reducing order: the rows of the member's system, whose
    envelope the skyline factorisation works in (`ddatai.fused.system`). On the graph of the
    blocks whose boxes come within a block size of each other, of reverse Cuthill–McKee and the
    blocks sorted by their boxes' centres (along y then x, and along x then y, each both ways),
    the order with the least factorisation work (`envelope_work`; reverse Cuthill–McKee where
    they tie). On a grid of blocks touching at corners RCM's fronts are anti-diagonals, each
    coupled to the one two ahead, and the rows of the grid take ~35 % less work at 64 blocks
    (benchmarks/results/small_models_fused_step.md)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import reverse_cuthill_mckee

    free = np.flatnonzero(~model.block_fixed)
    if len(free) <= 2:
        return free
    starts = model.vertex_offset[:-1]
    lo = np.minimum.reduceat(xy, starts, axis=0)[free]
    hi = np.maximum.reduceat(xy, starts, axis=0)[free]
    margin = 0.25 * float(np.median(np.max(hi - lo, axis=1))) + model.search_distance
    i, j = np.triu_indices(len(free), 1)
    near = (lo[i, 0] - margin <= hi[j, 0]) & (lo[j, 0] - margin <= hi[i, 0]) & \
        (lo[i, 1] - margin <= hi[j, 1]) & (lo[j, 1] - margin <= hi[i, 1])
    i, j = i[near], j[near]
    graph = coo_matrix((np.ones(2 * len(i)), (np.concatenate([i, j]), np.concatenate([j, i]))),
                       shape=(len(free), len(free))).tocsr()
    candidates = [reverse_cuthill_mckee(graph, symmetric_mode=True)]
    centre = 0.5 * (lo + hi)
    for major, minor in ((1, 0), (0, 1)):
        along = np.lexsort((centre[:, minor], centre[:, major]))
        candidates += [along, along[::-1]]
    return free[min(candidates, key=lambda order: envelope_work(order, i, j))]


def envelope_work(order: np.ndarray, i: np.ndarray, j: np.ndarray) -> int:
    """Σ over the block-rows of the envelope's width squared (in blocks) where the blocks are
    numbered in ``order`` and block pairs (i, j) are coupled: the skyline factorisation's work
    up to a constant (n·w² for an envelope w wide)."""
    at = np.empty(len(order), dtype=np.int64)
    at[order] = np.arange(len(order))
    first = np.arange(len(order))
    np.minimum.at(first, np.maximum(at[i], at[j]), np.minimum(at[i], at[j]))
    return int(np.sum((np.arange(len(order)) - first + 1) ** 2))


def _memory_rows(memory, n_vertices: int):
    """(kind, vertex0, edge0 or vertex1) of each remembered contact (`contacts.contact_keys`)."""
    n = np.int64(n_vertices)
    vv = memory.kind == 1
    key = np.where(vv, memory.key - n * n, memory.key)
    return vv.astype(np.int32), (key // n).astype(np.int64), (key % n).astype(np.int64)


def frame_size(model) -> int:
    """Floats of one frame of ``model`` (`ddatai.fused.layout.FR_BLOCK`)."""
    points = len(model.fixed_point_block) + len(model.load_block) + len(model.measured_block)
    return 1 + L.FR_BLOCK * model.n_blocks + 2 * model.n_vertices + 2 * points


def frames_per_launch(member, launch_steps: int) -> int:
    return launch_steps // member.frame_every + 2 if member.frame_every > 0 else 0


def pack(members: list, launch_steps: int) -> dict:
    """The arrays of a launch of ``members`` (`Member`), each with room for ``launch_steps``
    history rows (and step records, and frames). Returns the arrays by
    `ddatai.fused.arrays.FIELDS` name."""
    M = len(members)
    sizes = []
    for mem in members:
        mo, st = mem.model, mem.state
        cap = mem.contacts or max(MIN_CONTACTS, CONTACTS_PER_VERTEX * mo.n_vertices, 2 * len(st.memory.key) + 8)
        mem.contacts = cap
        sizes.append((mo.n_blocks, mo.n_vertices, mo.n_free, cap, len(mo.fixed_point_block) + len(mo.load_block)
                      + len(mo.measured_block), len(mo.pair_key), len(mo.joint_tan_phi), len(mem.group)))
    s = np.array(sizes, np.int64).reshape(M, 8)
    off = np.zeros((M + 1, 8), np.int64)
    off[1:] = np.cumsum(s, axis=0)
    nf = s[:, 2]
    k_off = np.concatenate([[0], np.cumsum(2 * (6 * nf) ** 2)])
    x_size = L.N_XS * 6 * nf + np.array([m.model.params.oc_max_iterations + 2 for m in members])
    x_off = np.concatenate([[0], np.cumsum(x_size)])
    B, V, R, C, P, Q, J, G = (int(max(1, off[-1, k])) for k in range(8))
    f_size = np.array([frames_per_launch(m, launch_steps) * frame_size(m.model) for m in members], np.int64)
    f_off = np.concatenate([[0], np.cumsum(f_size)])

    def zeros(shape, dtype=np.float64):
        return np.zeros(shape, dtype)

    A = dict(
        mi=zeros((M, L.N_MI), np.int32), mf=zeros((M, L.N_MF)), ccount=zeros(M, np.int32),
        bint=zeros((B, L.N_BI), np.int32), bmat=zeros((B, L.N_BM)), bst=zeros((B, L.N_BS)),
        bgeo=zeros((B, L.N_BG)), bwork=zeros((B, L.N_BW)),
        rblock=zeros(R, np.int32), env=zeros(R, np.int32),
        vnext=zeros(V, np.int32), vprev=zeros(V, np.int32), vblock=zeros(V, np.int32), vjoint=zeros(V, np.int32),
        vxy=zeros((V, 2)), vxy0=zeros((V, 2)), vnew=zeros((V, 2)),
        cint=zeros((C, L.N_CI), np.int32), cf=zeros((C, L.N_CF)), cvec=zeros((C, 36)), clen=zeros(C),
        memi=zeros((C, L.N_MEMI), np.int32), memf=zeros((C, L.N_MEMF)),
        kmat=zeros(max(1, int(k_off[-1]))), xvec=zeros(max(1, int(x_off[-1]))),
        pint=zeros((P, 2), np.int32), pf=zeros((P, L.N_PF)), pj=zeros((Q, 3), np.int32), jf=zeros((J, 3)),
        gidx=zeros(G, np.int32),
        hist=zeros((max(1, M * launch_steps), 2)),
        rec=zeros((max(1, sum(launch_steps for m in members if m.record)), L.N_RC)),
        frame=zeros(max(1, int(f_off[-1]))),
    )
    rec_at = 0
    gravity = np.zeros(B)  # |g| of each block's member [m/s²]
    for k, mem in enumerate(members):
        mo, st, p = mem.model, mem.state, mem.model.params
        b0, v0, r0, c0, p0, q0, j0, g0 = (int(x) for x in off[k])
        nb, nv = mo.n_blocks, mo.n_vertices
        mi, mf = A["mi"][k], A["mf"][k]
        mi[L.MI_B0], mi[L.MI_B1], mi[L.MI_V0], mi[L.MI_V1] = b0, b0 + nb, v0, v0 + nv
        mi[L.MI_C0], mi[L.MI_CCAP], mi[L.MI_NF], mi[L.MI_R0] = c0, mem.contacts, mo.n_free, r0
        mi[L.MI_K0], mi[L.MI_X0] = k_off[k], x_off[k]
        mi[L.MI_P0], mi[L.MI_P1], mi[L.MI_Q0], mi[L.MI_Q1] = p0, p0 + s[k, 4], q0, q0 + s[k, 5]
        mi[L.MI_G0], mi[L.MI_G1] = g0, g0 + s[k, 7]
        mi[L.MI_H0], mi[L.MI_HCAP] = k * launch_steps, launch_steps
        mi[L.MI_S0], mi[L.MI_SCAP] = rec_at, launch_steps if mem.record else 0
        rec_at += launch_steps if mem.record else 0
        mi[L.MI_STATUS], mi[L.MI_STEP], mi[L.MI_QUIET] = L.RUNNING, st.step, mem.quiet
        mi[L.MI_STEP_END], mi[L.MI_OC_MAX], mi[L.MI_REST_STEPS] = mem.step_end, p.oc_max_iterations, mem.rest_steps
        mi[L.MI_FLAGS] = (L.FLAG_STATIC * p.static | L.FLAG_LAGGED * (p.oc_friction == "lagged") |
                          L.FLAG_BOND_SLIP * p.bond_breaks_on_slip | L.FLAG_BY_LOAD * (p.oc_force_reference == "load")
                          | L.FLAG_AUTO_PENALTY * (p.penalty is None) | L.FLAG_RECORD * mem.record
                          | L.FLAG_MIDSTEP * p.midstep_lever_arms)
        mi[L.MI_LAUNCH_STEPS], mi[L.MI_HAVE_ENERGY] = launch_steps, st.energy is not None
        mi[L.MI_F0], mi[L.MI_FCAP] = f_off[k], frames_per_launch(mem, launch_steps)
        mi[L.MI_FEVERY], mi[L.MI_FSIZE] = mem.frame_every, frame_size(mo)
        start_penalty = mem.start_penalty if mem.start_penalty is not None else mo.penalty
        mem.start_penalty = start_penalty
        for col, v in ((L.MF_TIME, st.time), (L.MF_DT, st.dt), (L.MF_ACCEL, st.accel), (L.MF_PENALTY, mo.penalty),
                       (L.MF_SHEAR, mo.shear_penalty), (L.MF_FIXED_PEN, mo.fixed_point_penalty),
                       (L.MF_ROUNDOFF, mo.force_roundoff), (L.MF_W0, mo.w0), (L.MF_MAX_STEP, mo.max_step),
                       (L.MF_D0, mo.search_distance), (L.MF_D9, mo.max_penetration), (L.MF_OPEN_TOL, mo.open_tol),
                       (L.MF_PEN_LIMIT, mo.penetration_limit), (L.MF_START_PEN, start_penalty),
                       (L.MF_ENERGY, st.energy or 0.0), (L.MF_T_END, mem.t_end), (L.MF_GX, mo.gravity[0]),
                       (L.MF_GY, mo.gravity[1]), (L.MF_STOP_AT, mem.stop_at), (L.MF_REST_LIMIT, mem.rest_limit),
                       (L.MF_DT_FIXED, p.dt or 0.0), (L.MF_DT_MAX, p.dt_max), (L.MF_DT_MIN_RATIO, p.dt_min_ratio),
                       (L.MF_DT_GROWTH, p.dt_growth), (L.MF_DT_CUT, p.dt_cut),
                       (L.MF_IMPACT, -1.0 if p.impact_overshoot is None else p.impact_overshoot),
                       (L.MF_DISP_REJECT, p.displacement_reject), (L.MF_CARRY, p.velocity_carry),
                       (L.MF_BETA, p.newmark_beta), (L.MF_OC_FORCE_TOL, p.oc_force_tolerance),
                       (L.MF_OC_STATE_TOL, p.oc_state_tolerance), (L.MF_H1, math.radians(p.angle_tolerance)),
                       (L.MF_SHEAR_RATIO, p.shear_ratio), (L.MF_FIXED_RATIO, p.fixed_point_ratio),
                       (L.MF_OPEN_RATIO, p.open_tolerance)):
            mf[col] = v
        # blocks
        bs = slice(b0, b0 + nb)
        A["bint"][bs, L.BI_V0] = mo.vertex_offset[:-1] + v0
        A["bint"][bs, L.BI_V1] = mo.vertex_offset[1:] + v0
        order = row_order(mo, st.vertex_xy)
        rows = np.full(nb, -1, np.int32)
        rows[order] = np.arange(len(order))
        A["bint"][bs, L.BI_ROW] = rows
        A["bint"][bs, L.BI_MEMBER] = k
        A["rblock"][r0:r0 + len(order)] = order + b0
        A["bmat"][bs, L.BM_RHO] = mo.block_density
        A["bmat"][bs, L.BM_C:L.BM_C + 9] = mo.block_elastic.reshape(nb, 9)
        A["bmat"][bs, L.BM_CINV:L.BM_CINV + 9] = mo.block_compliance.reshape(nb, 9)
        A["bst"][bs, L.BS_VEL:L.BS_VEL + 6] = st.block_velocity
        A["bst"][bs, L.BS_ACC:L.BS_ACC + 6] = st.block_accel
        A["bst"][bs, L.BS_STRESS:L.BS_STRESS + 3] = st.block_stress
        A["bst"][bs, L.BS_ROT] = st.block_rotation
        gravity[bs] = float(np.hypot(*mo.gravity))
        # vertices
        vs = slice(v0, v0 + nv)
        A["vnext"][vs] = mo.vertex_next + v0
        A["vprev"][vs] = mo.vertex_prev + v0
        A["vblock"][vs] = mo.vertex_block + b0
        A["vjoint"][vs] = mo.edge_joint + j0
        A["vxy"][vs] = st.vertex_xy
        A["vxy0"][vs] = mo.vertex_xy0
        # joints and overrides
        A["jf"][j0:j0 + s[k, 6], L.JF_TAN] = mo.joint_tan_phi
        A["jf"][j0:j0 + s[k, 6], L.JF_COH] = mo.joint_cohesion
        A["jf"][j0:j0 + s[k, 6], L.JF_TEN] = mo.joint_tensile
        if len(mo.pair_key):
            A["pj"][q0:q0 + s[k, 5], 0] = mo.pair_key // nb + b0
            A["pj"][q0:q0 + s[k, 5], 1] = mo.pair_key % nb + b0
            A["pj"][q0:q0 + s[k, 5], 2] = mo.pair_joint + j0
        # points: fixed, loads, measured
        at = p0
        for kind, blk, xy0, xy, forces in (
                (L.POINT_FIXED, mo.fixed_point_block, mo.fixed_point_xy0, st.fixed_point_xy, None),
                (L.POINT_LOAD, mo.load_block, mo.load_xy0, st.load_xy, mo.load_force),
                (L.POINT_MEASURED, mo.measured_block, mo.measured_xy0, st.measured_xy, None)):
            n = len(blk)
            if not n:
                continue
            A["pint"][at:at + n, L.PI_BLOCK] = blk + b0
            A["pint"][at:at + n, L.PI_KIND] = kind
            A["pf"][at:at + n, L.PF_X0:L.PF_Y0 + 1] = xy0
            A["pf"][at:at + n, L.PF_X:L.PF_Y + 1] = xy
            if forces is not None:
                A["pf"][at:at + n, L.PF_FX:L.PF_FY + 1] = np.asarray(forces, float).reshape(n, 2)
            at += n
        A["gidx"][g0:g0 + s[k, 7]] = np.asarray(mem.group, np.int32) + b0
        # the contact memory, sorted as today's path sorts it (by key)
        memory = st.memory
        nm = len(memory.key)
        mi[L.MI_NM] = nm
        if nm:
            kind, first, second = _memory_rows(memory, nv)
            cs = slice(c0, c0 + nm)
            A["memi"][cs, L.MEMI_KIND] = kind
            A["memi"][cs, L.MEMI_V0] = first + v0
            A["memi"][cs, L.MEMI_K2] = second + v0
            A["memi"][cs, L.MEMI_STATE] = memory.state
            A["memi"][cs, L.MEMI_LINE] = memory.line
            A["memi"][cs, L.MEMI_BOND] = memory.bond
            A["memi"][cs, L.MEMI_DIR] = memory.shear_dir
            A["memf"][cs, L.MEMF_OMEGA] = memory.omega
            A["memf"][cs, L.MEMF_DN] = memory.dn
            A["memf"][cs, L.MEMF_NF] = memory.normal_force
    _block_geometry(A, gravity)
    return A


def _block_geometry(A: dict, gravity: np.ndarray) -> None:
    """Every member's block geometry at its state and at its start (``bgeo``), computed over the
    launch's vertex arrays at once: each block's sums run over its own vertices only, so every
    figure is the one of `ddatai.model.Model.block_geometry` and `ddatai.kinematics.block_radius`
    of its member alone (a call per member cost ~70 µs of a study's sample). ``gravity``: |g|
    of each block's member [m/s²]."""
    from types import SimpleNamespace

    from ..geometry import polygon_integrals
    from ..kinematics import block_radius

    if not len(A["mi"]):
        return
    nb, nv = int(A["mi"][-1, L.MI_B1]), int(A["mi"][-1, L.MI_V1])
    offset = np.append(A["bint"][:nb, L.BI_V0], nv)
    block, nxt, xy, xy0 = A["vblock"][:nv], A["vnext"][:nv], A["vxy"][:nv], A["vxy0"][:nv]
    blocks = SimpleNamespace(vertex_block=block, vertex_offset=offset)  # what block_radius reads of a model
    now = polygon_integrals(xy, offset, block, nxt)
    start = polygon_integrals(xy0, offset, block, nxt)
    g = A["bgeo"][:nb]
    g[:, L.BG_AREA], g[:, L.BG_CX], g[:, L.BG_CY] = now["area"], now["centroid"][:, 0], now["centroid"][:, 1]
    g[:, L.BG_S1], g[:, L.BG_S2], g[:, L.BG_S3] = now["s1"], now["s2"], now["s3"]
    g[:, L.BG_RADIUS] = block_radius(blocks, xy, now["centroid"])
    g[:, L.BG_RADIUS0] = block_radius(blocks, xy0, start["centroid"])
    g[:, L.BG_LOAD] = A["bmat"][:nb, L.BM_RHO] * start["area"] * gravity[:nb]


def unpack_state(A: dict, k: int, member: Member):
    """Member k's `ddatai.model.State` as the arrays hold it (after an accepted step or at a
    step's start: a member that GROWs or DIVERTs changed nothing in the step it left)."""
    from ..model import ContactMemory

    mo = member.model
    mi, mf = A["mi"][k], A["mf"][k]
    b0, b1, v0, v1 = (int(mi[c]) for c in (L.MI_B0, L.MI_B1, L.MI_V0, L.MI_V1))
    c0, nm = int(mi[L.MI_C0]), int(mi[L.MI_NM])
    bst = A["bst"][b0:b1]
    nv = v1 - v0
    memi, memf = A["memi"][c0:c0 + nm], A["memf"][c0:c0 + nm]
    n = np.int64(nv)
    vv = memi[:, L.MEMI_KIND] == 1
    key = np.where(vv, n * n, 0) + (memi[:, L.MEMI_V0] - v0).astype(np.int64) * n + (memi[:, L.MEMI_K2] - v0)
    order = np.argsort(key, kind="stable")
    memory = ContactMemory(key=key[order], state=memi[order, L.MEMI_STATE].astype(np.int8),
                           line=memi[order, L.MEMI_LINE].astype(np.int8), omega=memf[order, L.MEMF_OMEGA].copy(),
                           bond=memi[order, L.MEMI_BOND].astype(bool),
                           shear_dir=memi[order, L.MEMI_DIR].astype(np.int8), dn=memf[order, L.MEMF_DN].copy(),
                           normal_force=memf[order, L.MEMF_NF].copy(),
                           kind=memi[order, L.MEMI_KIND].astype(np.int8))
    p0 = int(mi[L.MI_P0])
    nfix, nload, nmeas = len(mo.fixed_point_block), len(mo.load_block), len(mo.measured_block)
    pxy = A["pf"][p0:p0 + nfix + nload + nmeas, L.PF_X:L.PF_Y + 1]
    st = member.state
    return st.replace(
        time=float(mf[L.MF_TIME]), step=int(mi[L.MI_STEP]), vertex_xy=A["vxy"][v0:v1].copy(),
        block_velocity=bst[:, L.BS_VEL:L.BS_VEL + 6].copy(), block_accel=bst[:, L.BS_ACC:L.BS_ACC + 6].copy(),
        block_stress=bst[:, L.BS_STRESS:L.BS_STRESS + 3].copy(), block_rotation=bst[:, L.BS_ROT].copy(),
        fixed_point_xy=pxy[:nfix].copy().reshape(-1, 2), load_xy=pxy[nfix:nfix + nload].copy().reshape(-1, 2),
        measured_xy=pxy[nfix + nload:].copy().reshape(-1, 2), dt=float(mf[L.MF_DT]), accel=float(mf[L.MF_ACCEL]),
        memory=memory, energy=float(mf[L.MF_ENERGY]) if mi[L.MI_HAVE_ENERGY] else None, geometry=None)


def member_model(A: dict, k: int, member: Member):
    """Member k's model with the penalty its run has now (raised by the run where it followed the
    load, `ddatai.step.Stepper.follow_load`)."""
    p = float(A["mf"][k, L.MF_PENALTY])
    return member.model if p == member.model.penalty else member.model.with_penalty(p)

