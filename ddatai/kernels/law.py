"""The contact law and the open-close judgement: forces and state of every contact at a solution
(`ddatai.contact_law` documents the law and holds the NumPy twins), the contacts whose assumed
state must change, and the generalised forces of the law's contact forces (docs/method/dda.md
§2.8, §4.3)."""

import taichi as ti

from .common import (E0, E1, ES, F64_1, F64_2, F64_3, G0, G1, GS, I8_1, I8_2, I32_1, I32_2, KIND_VV, STATE_LOCK,
                     STATE_OPEN, STATE_SLIDE, LAW_CLOSED, LAW_DIRECTION, LAW_DN, LAW_DN_NOW, LAW_DS,
                     LAW_ENERGY, LAW_FN, LAW_FN_NOW, LAW_FRICTION_NOW, LAW_FT, LAW_FT_NOW, LAW_LINE,
                     LAW_STATE, LAW_STRENGTH, IN_BOND, IN_COHESION, IN_COUPLED, IN_LENGTH,
                     IN_LINE, IN_NORMAL_FORCE, IN_SHEAR_DIR, IN_STATE, IN_TAN_PHI, IN_TENSILE, _dot6)


@ti.kernel
def contact_law(cint: I32_2, cstate: I8_2, cvalue: F64_2, block_a: I32_1, block_b: I32_1,
                vec: F64_3, sca: F64_2, disp: F64_2, penalty: ti.f64, shear_penalty: ti.f64,
                penetration_limit: ti.f64, out_f: F64_2, out_i: I8_2):
    """The contact law at the displacements ``disp``, contact by contact (docs/method/dda.md
    §2.8, §4.3; ``ddatai.contact_law.contact_law`` documents it; its NumPy twin is ``contact_law_numpy``).

    ``cstate`` rows IN_* (field-major, (5, m)): the contact's state, line, coupled, bond, shear direction;
    ``cvalue`` rows: tan φ, cohesion, tensile strength, length, normal force of the last solve;
    ``sca`` the constant parts with the second-order shift already added. Writes the LAW_*
    rows of ``out_f`` ((10, m)) (forces, distances, the contact's spring energy) and ``out_i`` ((4, m)).
    """
    for c in range(cint.shape[0]):
        a = block_a[c]
        b = block_b[c]
        vv = cint[c, 0] == KIND_VV
        now = ti.cast(cstate[IN_STATE, c], ti.i32)
        coupled = cstate[IN_COUPLED, c] != 0
        bond = ti.cast(cstate[IN_BOND, c] != 0, ti.f64)
        tan_phi = cvalue[IN_TAN_PHI, c]
        cohesion = cvalue[IN_COHESION, c] * cvalue[IN_LENGTH, c] * bond
        dn0 = sca[c, 0] + _dot6(vec, c, E0, disp, a) + _dot6(vec, c, G0, disp, b)
        dn_now = dn0
        dn = dn0
        line = 0
        ds = 0.0
        if vv:
            # line 1: vertex1 (of block b) against an edge of block a
            dn1 = sca[c, 1] + _dot6(vec, c, E1, disp, b) + _dot6(vec, c, G1, disp, a)
            if cstate[IN_LINE, c] == 1:
                dn_now = dn1
            # the entrance line: the less penetrated, but never one the vertex was already
            # behind at the step start by more than the penetration limit (§2.8.7)
            behind0 = sca[c, 0] < -penetration_limit
            behind1 = sca[c, 1] < -penetration_limit
            if behind0 != behind1:
                line = ti.cast(behind0, ti.i32)
            else:
                line = ti.cast(dn1 > dn0, ti.i32)
            if line == 1:
                dn = dn1
        else:
            ds = sca[c, 2] + _dot6(vec, c, ES, disp, a) + _dot6(vec, c, GS, disp, b)
        allowance = bond * cvalue[IN_TENSILE, c] * cvalue[IN_LENGTH, c] / penalty
        closed = dn <= allowance
        strength = penalty * ti.max(-dn, 0.0) * tan_phi + cohesion
        stale = cvalue[IN_NORMAL_FORCE, c] * tan_phi + cohesion
        used = stale
        if coupled:
            used = strength
        trial = shear_penalty * ds
        stick = ti.abs(trial) <= used
        sign_ds = 0.0
        if ds > 0.0:
            sign_ds = 1.0
        elif ds < 0.0:
            sign_ds = -1.0
        ft = 0.0
        state = STATE_OPEN
        if closed:
            state = STATE_SLIDE
            if not vv:
                ft = sign_ds * used
                if stick:
                    ft = trial
                    state = STATE_LOCK
        # spring energy with the friction of the next solve: ½p·dn² (up to the tensile
        # strength), and the Huber function of ds (½k_s·ds², then linear at the friction)
        energy = 0.5 * penalty * allowance * allowance
        if dn <= allowance:
            energy = 0.5 * penalty * dn * dn
        if closed and not vv:
            limit = used / shear_penalty
            if ti.abs(ds) <= limit:
                energy += 0.5 * shear_penalty * ds * ds
            else:
                energy += used * (ti.abs(ds) - 0.5 * limit)
        # the forces of the contact's current state at this D
        fn_now = 0.0
        if now != STATE_OPEN:
            fn_now = -penalty * dn_now
        friction_now = stale
        if coupled:
            friction_now = cohesion - penalty * tan_phi * dn_now
        ft_now = 0.0
        if not vv:
            if now == STATE_LOCK:
                ft_now = trial
            elif now == STATE_SLIDE:
                ft_now = ti.cast(cstate[IN_SHEAR_DIR, c], ti.f64) * friction_now
        fn = 0.0
        if closed:
            fn = -penalty * dn
        out_f[LAW_DN, c] = dn
        out_f[LAW_DS, c] = ds
        out_f[LAW_FN, c] = fn
        out_f[LAW_FT, c] = ft
        out_f[LAW_STRENGTH, c] = strength
        out_f[LAW_DN_NOW, c] = dn_now
        out_f[LAW_FN_NOW, c] = fn_now
        out_f[LAW_FT_NOW, c] = ft_now
        out_f[LAW_FRICTION_NOW, c] = friction_now
        out_f[LAW_ENERGY, c] = energy
        out_i[LAW_LINE, c] = ti.cast(line, ti.i8)
        out_i[LAW_CLOSED, c] = ti.cast(closed, ti.i8)
        out_i[LAW_STATE, c] = ti.cast(state, ti.i8)
        direction = -1
        if ds >= 0.0:
            direction = 1
        out_i[LAW_DIRECTION, c] = ti.cast(direction, ti.i8)


@ti.kernel
def violations(cint: I32_2, cstate: I8_2, cvalue: F64_2, block_a: I32_1, block_b: I32_1,
               law_f: F64_2, law_i: I8_2, level: F64_1, fixed: I8_1, penalty: ti.f64,
               force_tolerance: ti.f64, by_load: ti.i32, state_tolerance: ti.f64, roundoff: ti.f64,
               bad: I8_1):
    """Contacts whose assumed state must change given the law at the solution
    (``ddatai.contact_law.violations`` documents the rules; the NumPy twin is ``violations_numpy``).
    ``level`` enters as each block's weight and leaves as the load the block carries (its
    weight or its largest contact force). ``by_load``: the force tolerance is a fraction of
    that load, of the contact's free blocks only (1; ``fixed``: each block's flag), or of the
    contact's own strength (0; ``Params.oc_force_reference``)."""
    for c in range(cint.shape[0]):
        f = ti.abs(law_f[LAW_FN, c])
        ti.atomic_max(level[block_a[c]], f)
        ti.atomic_max(level[block_b[c]], f)
    for c in range(cint.shape[0]):
        vv = cint[c, 0] == KIND_VV
        now = ti.cast(cstate[IN_STATE, c], ti.i32)
        strength = law_f[LAW_STRENGTH, c]
        carried = ti.max(level[block_a[c]], level[block_b[c]])
        tensile = 0.0
        if cstate[IN_BOND, c] != 0:
            tensile = cvalue[IN_TENSILE, c] * cvalue[IN_LENGTH, c]
        strict = force_tolerance * strength + roundoff
        strict_tension = force_tolerance * tensile + roundoff
        if by_load != 0:
            free_carried = 0.0
            if fixed[block_a[c]] == 0:
                free_carried = level[block_a[c]]
            if fixed[block_b[c]] == 0:
                free_carried = ti.max(free_carried, level[block_b[c]])
            strict = force_tolerance * free_carried + roundoff
            strict_tension = strict
        out = False
        if not vv and now == STATE_LOCK:
            # Coulomb: a locked contact holds at most its strength
            out = ti.abs(law_f[LAW_FT_NOW, c]) > strength + strict
        if not vv and now == STATE_SLIDE and law_i[LAW_CLOSED, c] != 0:
            # a sliding contact's friction is the strength of this solve
            out = out or ti.abs(law_f[LAW_FRICTION_NOW, c] - strength) > strict
        if now != STATE_OPEN:
            out = out or -law_f[LAW_FN_NOW, c] > tensile + strict_tension
        loose = state_tolerance * carried + roundoff
        out = out or ti.abs(law_f[LAW_FN_NOW, c] - law_f[LAW_FN, c]) > loose or \
            ti.abs(law_f[LAW_FT_NOW, c] - law_f[LAW_FT, c]) > loose
        if vv and now != STATE_OPEN and law_i[LAW_LINE, c] != cstate[IN_LINE, c]:
            out = out or penalty * ti.abs(law_f[LAW_DN, c] - law_f[LAW_DN_NOW, c]) > loose
        bad[c] = ti.cast(out, ti.i8)


@ti.kernel
def internal_force(block_a: I32_1, block_b: I32_1, dof: I32_1, vec: F64_3, law_f: F64_2, law_i: I8_2,
                   out: F64_1, serial: ti.template()):
    """Generalised forces of the law's contact forces (``ddatai.contact_law.internal_force``,
    which holds the NumPy twin): p·dn·∇dn of each closed contact's active line and f_t·∇ds,
    added into ``out`` (6 per free block). ``serial`` as in `assemble_contacts`."""
    ti.loop_config(serialize=serial)
    for c in range(block_a.shape[0]):
        pull = -law_f[LAW_FN, c]  # p·dn of a closed contact, 0 for an open one
        ft = law_f[LAW_FT, c]
        sa = E0
        sb = G0
        if law_i[LAW_LINE, c] == 1:
            sa = G1
            sb = E1
        ra = dof[block_a[c]]
        rb = dof[block_b[c]]
        for k in ti.static(range(6)):
            if ra >= 0:
                ti.atomic_add(out[6 * ra + k], pull * vec[c, sa, k] + ft * vec[c, ES, k])
            if rb >= 0:
                ti.atomic_add(out[6 * rb + k], pull * vec[c, sb, k] + ft * vec[c, GS, k])
