"""The fused engine's array layout: columns of its per-member, per-block, per-contact tables and
the status codes of a member (plain integers, shared by the packing in NumPy and the Taichi
functions; no Taichi here).

Every member of a launch owns contiguous ranges of the global arrays: its blocks, vertices,
points, joint overrides, group blocks, a contact region of fixed capacity (and the same region
of the contact memory), rows of the linear system, and a slab of the matrix and vector arrays.
Indices in the tables are global (a member's vertex ``v`` of its own model is ``v + V0``).
"""

from __future__ import annotations

# ------------------------------------------------------------------ per member, int32 (``mi``)
(MI_B0, MI_B1, MI_V0, MI_V1, MI_C0, MI_CCAP, MI_NC, MI_NM, MI_NF, MI_R0, MI_K0, MI_X0,
 MI_P0, MI_P1, MI_Q0, MI_Q1, MI_G0, MI_G1, MI_H0, MI_HCAP, MI_HN, MI_S0, MI_SCAP, MI_SN,
 MI_STATUS, MI_CAUSE, MI_STEP, MI_QUIET, MI_STEP_END, MI_OC_MAX, MI_REST_STEPS, MI_FLAGS,
 MI_LAUNCH_STEPS, MI_HAVE_ENERGY, MI_RAISED, MI_F0, MI_FCAP, MI_FN, MI_FEVERY, MI_FSIZE) = range(40)
N_MI = 40

# bits of ``MI_FLAGS`` (the member's Params as switches)
FLAG_STATIC = 1          # Params.static
FLAG_LAGGED = 2          # Params.oc_friction == "lagged"
FLAG_BOND_SLIP = 4       # Params.bond_breaks_on_slip
FLAG_BY_LOAD = 8         # Params.oc_force_reference == "load"
FLAG_AUTO_PENALTY = 16   # Params.penalty is None (the penalty follows the load)
FLAG_RECORD = 32         # write a step record a step (``rec``)
FLAG_MIDSTEP = 64        # Params.midstep_lever_arms (set by ``engine.Session``)

# ------------------------------------------------------------------ per member, float64 (``mf``)
(MF_TIME, MF_DT, MF_ACCEL, MF_PENALTY, MF_SHEAR, MF_FIXED_PEN, MF_ROUNDOFF, MF_W0, MF_MAX_STEP,
 MF_D0, MF_D9, MF_OPEN_TOL, MF_PEN_LIMIT, MF_START_PEN, MF_ENERGY, MF_T_END, MF_GX, MF_GY,
 MF_STOP_AT, MF_REST_LIMIT, MF_DT_FIXED, MF_DT_MAX, MF_DT_MIN_RATIO, MF_DT_GROWTH, MF_DT_CUT,
 MF_DISP_REJECT, MF_CARRY, MF_BETA, MF_OC_FORCE_TOL, MF_OC_STATE_TOL, MF_H1, MF_SHEAR_RATIO,
 MF_FIXED_RATIO, MF_OPEN_RATIO, MF_DISPLACEMENT, MF_IMPACT) = range(36)
N_MF = 36
# MF_IMPACT: Params.impact_overshoot (−1: None, impacts off; set by ``engine.Session``)

# ------------------------------------------------------------------ per block
# ``bint`` (int32): first and end vertex, row in the member's system (-1: fixed), member
BI_V0, BI_V1, BI_ROW, BI_MEMBER = range(4)
N_BI = 4
# ``bmat`` (float64): density, C (3×3, row-major), C⁻¹
BM_RHO = 0
BM_C = 1
BM_CINV = 10
N_BM = 19
# ``bst`` (float64): generalized velocity (6), acceleration (6), stress (3), rotation
BS_VEL, BS_ACC, BS_STRESS, BS_ROT = 0, 6, 12, 15
N_BS = 16
# ``bgeo`` (float64): area, centroid, central moments, radius (now), radius at the start,
# weight (the open-close judgement's smallest load of the block)
BG_AREA, BG_CX, BG_CY, BG_S1, BG_S2, BG_S3, BG_RADIUS, BG_RADIUS0, BG_LOAD = range(9)
N_BG = 9
# ``bwork`` (float64): the iterate D (6), the solve's solution (6), the last iterate (6), the
# rotation of the second-order terms, the load a block carries (the judgement's level)
BW_D, BW_SOL, BW_PREV, BW_ROT, BW_LEVEL = 0, 6, 12, 18, 19
# an impact (``ddatai.impacts``): the block is impacted (1.0), its velocity and acceleration
# before the plastic impact at the step's start
BW_IMPACT, BW_V0, BW_A0 = 20, 21, 27
# the rotation's second-order terms, once a solve (`iterate.open_close`): cos r − 1, sin r − r,
# cos(r/2) − 1, sin(r/2) of BW_ROT's r (§5.3)
BW_TRIG = 33
# the block's bounding box at the step's start (`contacts.detect`): lower x, y, upper x, y
BW_BOX = 37
N_BW = 41

# ------------------------------------------------------------------ per contact
# ``cint`` (int32): kind, vertex0, edge0, vertex1, edge1 (the narrow phase's five columns), then
# the open-close state, the state at the step's start, and the law's integer fields of two
# evaluations (slot 0: at the solution; slot 1: at the line search's trial point)
(CI_KIND, CI_V0, CI_E0, CI_V1, CI_E1, CI_STATE, CI_LINE, CI_BOND, CI_DIR, CI_COUPLED, CI_JOINT,
 CI_A, CI_B, CI_STATE0, CI_LINE0, CI_BOND0, CI_DIR0, CI_COUPLED0) = range(18)
CI_LAW = 18               # + 5·slot + (line, closed, state, direction, bad)
LI_LINE, LI_CLOSED, LI_STATE, LI_DIR, LI_BAD = range(5)
CI_CLOSING = CI_LAW + 10   # closing within the step (``impacts.approach_bound``)
N_CI = CI_LAW + 11
# ``cf`` (float64): length, ω, dn, ds, normal force, tanφ, c, T, the constant parts (3), their
# second-order shift (3), the step-start dn, ds, N, then the law's float fields of two evaluations
(CF_LEN, CF_OMEGA, CF_DN, CF_DS, CF_NF, CF_TAN, CF_COH, CF_TEN, CF_SCA, _S1, _S2, CF_SHIFT, _H1, _H2,
 CF_DN0, CF_DS0, CF_NF0) = range(17)
CF_LAW = 17               # + 10·slot + the fields below
(LF_DN, LF_DS, LF_FN, LF_FT, LF_STRENGTH, LF_DN_NOW, LF_FN_NOW, LF_FT_NOW, LF_FRICTION_NOW,
 LF_ENERGY) = range(10)
# the step start's rotation column of the contact vertex's slots (E0, E1, ES), which each solve
# turns to its mid-step lever arm (``contacts.lever_arms``, ``ddatai.lever_arm``)
CF_ARM = CF_LAW + 20
N_CF = CF_LAW + 23
# ``memi`` (int32) / ``memf`` (float64): the contact memory of the last step (§3.7), sorted by key
MEMI_KIND, MEMI_V0, MEMI_K2, MEMI_STATE, MEMI_LINE, MEMI_BOND, MEMI_DIR = range(7)
N_MEMI = 7
MEMF_OMEGA, MEMF_DN, MEMF_NF = range(3)
N_MEMF = 3

# ------------------------------------------------------------------ the member's vector slab
# ``xvec[MI_X0 + slot·n : ... + n]`` (n = 6 × free blocks): the right-hand side of a solve, the
# block terms F0, the block terms with the second-order loads (the line search's energy), the
# triangular solves' scratch, the line search's gradient; then, at 5n, the hashes of the sets of
# contact states of a last try (at most ``MI_OC_MAX`` + 1)
XS_RHS, XS_F0, XS_BRHS, XS_Y, XS_GRAD, XS_HASH = range(6)
N_XS = 5

# ------------------------------------------------------------------ points, joints, records
PI_BLOCK, PI_KIND = range(2)   # ``pint``: block, kind (POINT_*)
POINT_FIXED, POINT_LOAD, POINT_MEASURED = range(3)
PF_X0, PF_Y0, PF_X, PF_Y, PF_FX, PF_FY = range(6)   # ``pf``: initial and current position, force
N_PF = 6
JF_TAN, JF_COH, JF_TEN = range(3)   # ``jf``: tanφ, c [Pa], T [Pa]
# ``rec``: one row a step, the float fields of ``ddatai.records.STEP_DTYPE`` that the engine
# fills (the wall-time fields are the launch's, spread over its steps by the driver)
(RC_TIME, RC_DT, RC_OC, RC_OC_TOTAL, RC_CUTS, RC_CONTACTS, RC_CLOSED, RC_MAX_PEN, RC_MAX_DISP,
 RC_KINETIC, RC_GRAVITATIONAL, RC_STRAIN, RC_CONTACT, RC_EXTERNAL, RC_FRICTION, RC_INTEGRATOR,
 RC_COULOMB, RC_PENALTY) = range(18)
N_RC = 18

# ``frame``: a member's frames (every ``MI_FEVERY`` steps and at its end), each ``MI_FSIZE`` floats:
# the time, then per block (centroid x, y, rotation, velocity x, y, angular velocity, stress σx,
# σy, τxy), then every vertex (x, y), then every point (x, y) in the order fixed, load, measured
FR_BLOCK = 9

# ------------------------------------------------------------------ member status
RUNNING = 0           # steps remain (the launch's step budget ended)
DONE = 1              # reached its end time or step count
STOP_MOVED = 2        # its group moved past the stop displacement (kgm: stopped early)
STOP_REST = 3         # its free blocks have been at rest for the rest steps (kgm: at rest)
GROW = 4              # its contacts outgrew their region: re-launched with more, from the step's start
DIVERT = 5            # a step left what the engine does: continued on today's path from the step's start
WAITING = 6           # not started (a member already finished or handed over)

# causes of DIVERT (``MI_CAUSE``)
CAUSE_NONE = 0
CAUSE_CYCLES = 1      # the step's last try at the shortest Δt (today's path holds cycling contacts)
CAUSE_FAILED = 2      # no Δt above the shortest converged (today's path reports the error)
