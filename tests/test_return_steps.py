"""The return mapping's line search (`ddatai.return_steps.line_search`, docs/method/dda.md §8.12)
against the slope of its energy written out in full: ½DᵀKD − FᵀD of the blocks plus ½p·dn² of
each closed contact on its less penetrated line (up to the tensile allowance) and ½k_s·ds² of
each closed shearing one, bisected on α ∈ (0, 1]. Where every contact is vertex-edge, the search
takes line 0 alone (line 1 is −∞ at rate 0): its α must be the full slope's to the bit, on
models with vertex-vertex contacts and without."""

from __future__ import annotations

import numpy as np

from ddatai.contacts import Contacts
from ddatai.layout import KIND, VE, VV
from ddatai.model import ContactMemory, build_model
from ddatai.return_mapping import Frame
from ddatai.return_steps import LINE_SEARCH_BISECTIONS, _measures, line_search
from ddatai.step import Stepper
from cases import random_jointed_scene
from test_stage_screen import group_model


def reference_alpha(stepper, frame, contacts, sca, disp, step, shearing) -> float:
    model = stepper.model
    rows = stepper.free_idx
    x, v = disp[rows].ravel(), step[rows].ravel()
    kv = frame.k_blocks @ v
    curvature, slope0 = float(v @ kv), float(kv @ x) - float(frame.rhs @ v)
    dn0, dn1, ds = _measures(frame.vec, sca, contacts, disp)
    r0, r1, rs = _measures(frame.vec, None, contacts, step)
    allowance = np.where(contacts.bond, contacts.tensile * contacts.length / model.penalty, 0.0)

    def slope(a):
        n0, n1 = dn0 + a * r0, dn1 + a * r1
        one = n1 > n0
        dn = np.where(one, n1, n0)
        closed = dn <= allowance
        normal = np.where(closed, model.penalty * dn, 0.0)
        shear = np.where(closed & shearing, model.shear_penalty * (ds + a * rs), 0.0)
        return curvature * a + slope0 + float(normal @ np.where(one, r1, r0)) + float(shear @ rs)

    if slope(1.0) <= 0.0:
        return 1.0
    lo, hi = 0.0, 1.0
    for _ in range(LINE_SEARCH_BISECTIONS):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if slope(mid) < 0.0 else (lo, mid)
    return max(lo, 1.0 / 2 ** LINE_SEARCH_BISECTIONS)


def test_the_line_search_is_the_full_slope_s_bisection_with_and_without_vertex_vertex_contacts():
    rng = np.random.default_rng(5)
    from scenes import example_2

    # Example II's group (vertex-edge contacts only) at two strengths, random jointed squares
    models = [group_model(example_2, friction=phi, cohesion=20e3) for phi in (18.0, 24.0)] + \
        [build_model(random_jointed_scene(seed)) for seed in range(3)]
    kinds = {True: [], False: []}  # has vertex-vertex contacts: the αs found
    for model in models:
        stepper, state = Stepper(model), model.initial_state()
        geom = model.block_geometry(state.vertex_xy)
        contacts = Contacts.start(model, state.vertex_xy, *stepper.detect(state.vertex_xy), ContactMemory.empty(), True)
        frame = Frame.build(stepper, state, geom, contacts, 1.0)
        shearing = contacts.cint[:, KIND] == VE
        free = ~model.block_fixed[:, None]
        for scale in (1e-6, 1e-4, 1e-2):
            disp = np.where(free, rng.normal(0.0, 1e-6, (model.n_blocks, 6)), 0.0)
            step = np.where(free, rng.normal(0.0, scale, (model.n_blocks, 6)), 0.0)
            alpha = line_search(stepper, frame, contacts, frame.sca, disp, step, shearing)
            assert alpha == reference_alpha(stepper, frame, contacts, frame.sca, disp, step, shearing)
            kinds[bool(np.count_nonzero(contacts.cint[:, KIND] == VV))].append(alpha)
    for found in kinds.values():  # both paths, and bisections among them
        assert found and min(found) < 1.0
