"""Contact detection: Taichi kernels against the NumPy reference, and the contact geometry of
docs/method/dda.md §2.8, §3 on hand-made cases (sign of dn, edge-edge lengths, vertex-vertex)."""

import numpy as np
import pytest

import ddatai as dd
from cases import ROCK, perturbed_vertices, random_jointed_scene
from ddatai import reference
from ddatai.assembly import contact_vectors
from ddatai.contacts import Contacts, _Buffers, broad_phase, detect_contacts
from ddatai.geometry import displacement_matrix
from ddatai.model import ContactMemory, ContactState, build_model
from ddatai.step import Stepper


@pytest.mark.parametrize("seed", range(12))
def test_taichi_detection_equals_reference(seed):
    """Broad phase and narrow phase agree exactly with the brute-force NumPy reference."""
    model = build_model(random_jointed_scene(seed))
    xy = perturbed_vertices(model, seed + 100, shift=0.2 * model.search_distance)
    assert np.array_equal(broad_phase(model, xy, model.search_distance, _Buffers()),
                          reference.broad_phase(model, xy, model.search_distance))
    cint, length = detect_contacts(model, xy)
    cint_r, length_r = reference.detect_contacts(model, xy)
    assert len(cint) > 0
    assert np.array_equal(cint, cint_r)
    assert np.allclose(length, length_r, rtol=1e-12, atol=1e-12)


def test_broad_phase_with_big_boxes_equals_reference():
    """Blocks larger than 4× the median size take the all-against-one path."""
    scene = dd.Scene()
    scene.add_block([(-50, -5), (50, -5), (50, 0), (-50, 0)], material=ROCK, fixed=True)
    scene.add_block([(-50, 0), (-45, 0), (-45, 40), (-50, 40)], material=ROCK, fixed=True)
    rng = np.random.default_rng(3)
    for k in range(60):
        x, y = -44 + 1.5 * (k % 12) + rng.uniform(0, 0.5), 1.0 * (k // 12) + rng.uniform(0, 0.05)
        scene.add_block([(x, y), (x + 0.9, y), (x + 0.9, y + 0.9), (x, y + 0.9)], material=ROCK)
    scene.add_block([(10, 35), (30, 35), (30, 38), (10, 38)], material=ROCK)  # big and free
    model = build_model(scene)
    xy = model.vertex_xy0
    for margin in (model.search_distance, 3.0):
        assert np.array_equal(broad_phase(model, xy, margin, _Buffers()),
                              reference.broad_phase(model, xy, margin))


def _model(*blocks, fixed=(0,)):
    scene = dd.Scene()
    for k, b in enumerate(blocks):
        scene.add_block(b, material=ROCK, fixed=k in fixed)
    return build_model(scene)


def test_block_on_base_is_two_edge_edge_contacts():
    m = _model([(-2, -1), (3, -1), (3, 0), (-2, 0)], [(0, 0), (1, 0), (1, 1), (0, 1)])
    cint, length = detect_contacts(m, m.vertex_xy0)
    assert len(cint) == 2
    assert np.all(cint[:, 0] == dd.ContactKind.VE)
    assert np.all(m.vertex_block[cint[:, 1]] == 1)  # the block's corners against the base edge
    assert np.allclose(length, 0.5)                   # half of the 1 m overlap each


def test_offset_edges_give_one_vertex_from_each_block():
    """Overlap [1.5, 2] of two parallel edges: the square's corner at 1.5 on the base's edge,
    and the base's corner at 2 on the square's edge (§3.6)."""
    m = _model([(0, -1), (2, -1), (2, 0), (0, 0)], [(1.5, 0), (2.5, 0), (2.5, 1), (1.5, 1)])
    cint, length = detect_contacts(m, m.vertex_xy0)
    assert len(cint) == 2
    owners = sorted(m.vertex_block[cint[:, 1]])
    assert owners == [0, 1]
    assert np.allclose(length, 0.25)


def test_corner_to_corner_is_vertex_vertex():
    m = _model([(-1, -1), (0, -1), (0, 0), (-1, 0)], [(0.0, 1e-4), (1, 1e-4), (1, 1), (0.0, 1)])
    cint, _ = detect_contacts(m, m.vertex_xy0)
    assert len(cint) == 1 and cint[0, 0] == dd.ContactKind.VV


def test_concave_corner_gives_vertex_against_both_edges():
    """A square corner pushed into the concave corner of an L-shaped block."""
    L = [(0, 0), (3, 0), (3, 1), (1, 1), (1, 3), (0, 3)]
    m = _model(L, [(1 + 1e-4, 1 + 1e-4), (2, 1 + 1e-4), (2, 2), (1 + 1e-4, 2)])
    cint, _ = detect_contacts(m, m.vertex_xy0)
    corner = m.vertex_offset[1]  # the square's first vertex, nearest the concave corner
    hits = cint[cint[:, 1] == corner]
    assert len(hits) == 2 and np.all(hits[:, 0] == dd.ContactKind.VE)
    assert set(m.vertex_block[hits[:, 2]]) == {0}


def test_normal_distance_sign():
    """A vertex 1 m above a horizontal edge has dn = +1; 0.1 m inside it, dn = −0.1 (§7j)."""
    m = _model([(-2, -1), (3, -1), (3, 0), (-2, 0)], [(0, 1), (1, 1.5), (0.5, 2.5)])
    Stepper(m)  # starts Taichi on the model's arch
    # vertex 0 of block 1 against the top edge of the base (edge from vertex 2 to vertex 3)
    cint = np.array([[0, m.vertex_offset[1], 2, -1, -1]], np.int32)
    for drop, expect in ((0.0, 1.0), (1.1, -0.1)):
        xy = m.vertex_xy0.copy()
        xy[m.vertex_offset[1]:, 1] -= drop
        c = Contacts.start(m, xy, cint, np.zeros(1), ContactMemory.empty(), False)
        _, sca = contact_vectors(m, xy, m.block_geometry(xy), c)
        assert sca[0, 0] == pytest.approx(expect, abs=1e-14)
        assert c.dn[0] == pytest.approx(expect, abs=1e-14)


def _exact_dn_ds(P1, P2, P3, omega, l0):
    """Δ/l0 and (P1 − P0)·(P3 − P2)/l0 of P1 against the line P2 -> P3, with the edge length
    l0 held at its step-start value as in DDA's linearisation (§2.8.1)."""
    dn = ((P2[0] - P1[0]) * (P3[1] - P1[1]) - (P2[1] - P1[1]) * (P3[0] - P1[0])) / l0
    P0 = (1 - omega) * P2 + omega * P3
    return dn, np.dot(P1 - P0, P3 - P2) / l0


def _random_contacts(seed):
    """A random jointed scene with perturbed vertices, its detected contacts and random lock
    positions ω; returns (model, vertex_xy, cint, contacts, rng)."""
    model = build_model(random_jointed_scene(seed))
    xy = perturbed_vertices(model, seed, shift=0.1 * model.search_distance)
    cint, length = detect_contacts(model, xy)
    rng = np.random.default_rng(seed)
    c = Contacts.start(model, xy, cint, length, ContactMemory.empty(), False)
    c.omega[:] = rng.uniform(0, 1, c.n)
    return model, xy, cint, c, rng


@pytest.mark.parametrize("seed", range(4))
def test_contact_vectors_are_derivatives(seed):
    """e, g, e_s, g_s equal finite differences of dn, ds with respect to D (§7j), and the
    Taichi kernel equals the reference."""
    model, xy, cint, c, rng = _random_contacts(seed)
    geom = model.block_geometry(xy)
    vec, sca = contact_vectors(model, xy, geom, c)
    vec_r, sca_r = reference.contact_vectors(model, xy, geom["centroid"], cint, c.omega)
    assert np.allclose(vec, vec_r, rtol=1e-11, atol=1e-11 * np.abs(vec_r).max())
    assert np.allclose(sca, sca_r, rtol=1e-11, atol=1e-12)
    h = 1e-7
    nxt = model.vertex_next
    for k in range(min(c.n, 25)):
        kind, v0, e0 = cint[k, :3]
        if kind != dd.ContactKind.VE:
            continue
        i, j = model.vertex_block[v0], model.vertex_block[e0]
        pts = [xy[v0], xy[nxt[e0]], xy[e0]]
        owner = [i, j, j]
        l0 = np.linalg.norm(pts[2] - pts[1])
        base_dn, base_ds = _exact_dn_ds(*pts, c.omega[k], l0)
        for blk, slot_n, slot_s in ((i, 0, 4), (j, 1, 5)):
            if i == j:
                continue
            for a in range(6):
                D = np.zeros(6)
                D[a] = h
                moved = [p + (displacement_matrix(p, geom["centroid"][o]) @ D if o == blk else 0)
                         for p, o in zip(pts, owner)]
                dn, ds = _exact_dn_ds(*moved, c.omega[k], l0)
                scale = 1.0 + np.abs(vec[k, slot_n]).max()
                assert (dn - base_dn) / h == pytest.approx(vec[k, slot_n, a], abs=1e-6 * scale)
                scale = 1.0 + np.abs(vec[k, slot_s]).max()
                assert (ds - base_ds) / h == pytest.approx(vec[k, slot_s, a], abs=1e-6 * scale)


def test_common_translation_leaves_contacts_unchanged():
    """Rigid-body invariance: the same translation of both blocks changes no dn or ds."""
    model = build_model(random_jointed_scene(5))
    xy = perturbed_vertices(model, 1, shift=0.1 * model.search_distance)
    cint, length = detect_contacts(model, xy)
    c = Contacts.start(model, xy, cint, length, ContactMemory.empty(), False)
    vec, _ = contact_vectors(model, xy, model.block_geometry(xy), c)
    for D in (np.array([1.0, 0, 0, 0, 0, 0]), np.array([0, 1.0, 0, 0, 0, 0])):
        assert np.allclose(vec[:, 0] @ D + vec[:, 1] @ D, 0, atol=1e-12)
        ve = cint[:, 0] == dd.ContactKind.VE
        assert np.allclose(vec[ve, 4] @ D + vec[ve, 5] @ D, 0, atol=1e-12)


def test_contact_memory_transfer():
    """A persisting locked contact keeps its lock position ω; a sliding one keeps its state and
    sliding direction but is re-anchored; a new contact starts open (§3.7)."""
    m = _model([(-2, -1), (3, -1), (3, 0), (-2, 0)], [(0, 0), (1, 0), (1, 1), (0, 1)])
    cint, length = detect_contacts(m, m.vertex_xy0)
    first = Contacts.start(m, m.vertex_xy0, cint, length, ContactMemory.empty(), True)
    assert np.all(first.state == ContactState.LOCK) and np.all(first.bond)
    first.state[:] = [ContactState.LOCK, ContactState.SLIDE]
    first.shear_dir[:] = [1, -1]
    first.omega[:] = [0.3, 0.7]
    mem = first.memory()
    assert list(mem.bond) == [True, False]  # a sliding contact loses its bond
    again = Contacts.start(m, m.vertex_xy0, cint, length, mem, False)
    assert list(again.state) == [ContactState.LOCK, ContactState.SLIDE]
    assert again.omega[0] == 0.3
    assert again.omega[1] != 0.7 and again.shear_dir[1] == -1
    fresh = Contacts.start(m, m.vertex_xy0, cint, length, ContactMemory.empty(), False)
    assert np.all(fresh.state == ContactState.OPEN)


@pytest.mark.parametrize("seed", range(3))
def test_second_order_shift_kernel_equals_reference_and_derivative(seed):
    """The second-order rotation shift (§5.3) is ∂Δ/∂P·q and ∂s/∂P·q: the Taichi kernel equals
    the NumPy twin, and both equal the change of the exact dn, ds when every vertex moves by a
    small q (first order in q)."""
    from ddatai import kernels

    model, xy, cint, c, rng = _random_contacts(seed)
    eps = 1e-7
    q = eps * rng.standard_normal(xy.shape)
    shift = np.zeros((c.n, 3))
    kernels.second_order_shift(xy, model.vertex_next, q, c.cint, c.omega, shift)
    shift_r = reference.second_order_shift(model, xy, q, c.cint, c.omega)
    assert np.allclose(shift, shift_r, rtol=1e-12, atol=1e-12 * eps)
    nxt = model.vertex_next
    for k in range(c.n):
        kind, v0, e0 = cint[k, :3]
        pts = [xy[v0], xy[nxt[e0]], xy[e0]]
        moved = [pts[0] + q[v0], pts[1] + q[nxt[e0]], pts[2] + q[e0]]
        l0 = np.linalg.norm(pts[2] - pts[1])
        dn0, ds0 = _exact_dn_ds(*pts, c.omega[k], l0)
        dn1, ds1 = _exact_dn_ds(*moved, c.omega[k], l0)
        # what the linear shift leaves out is second order in q (~|q|²/l0), plus round-off of
        # the subtraction of O(size) distances
        tol = 10 * np.abs(q).max() ** 2 / l0 + 1e-14 * (1 + np.abs(xy).max())
        assert abs(shift[k, 0] - (dn1 - dn0)) < tol
        if kind == dd.ContactKind.VE:
            assert abs(shift[k, 2] - (ds1 - ds0)) < tol
        else:
            assert shift[k, 2] == 0.0
            v1, e1 = cint[k, 3:5]  # the second entrance line of a vertex-vertex contact
            pts = [xy[v1], xy[nxt[e1]], xy[e1]]
            moved = [pts[0] + q[v1], pts[1] + q[nxt[e1]], pts[2] + q[e1]]
            l1 = np.linalg.norm(pts[2] - pts[1])
            d0 = _exact_dn_ds(*pts, 0.0, l1)[0]
            d1 = _exact_dn_ds(*moved, 0.0, l1)[0]
            assert abs(shift[k, 1] - (d1 - d0)) < 10 * np.abs(q).max() ** 2 / l1 + 1e-14 * (1 + np.abs(xy).max())


def test_collapsed_edge_gets_no_contact_in_kernel_and_reference():
    """Guards of the narrow phase: an edge squeezed to zero length in a run (a block whose
    vertex coincides with its neighbour) has no normal; both paths skip it instead of dividing
    by zero, and agree on every other contact."""
    scene = dd.Scene()
    scene.add_block([(-2, -1), (3, -1), (3, 0), (-2, 0)], material=ROCK, fixed=True)
    scene.add_block([(0, 0), (1, 0), (1, 1), (0.5, 1.0 + 1e-3), (0, 1)], material=ROCK)
    scene.add_block([(0, 1.0 + 1e-3), (1, 1.0 + 1e-3), (1, 2), (0, 2)], material=ROCK)
    model = dd.build_model(scene)
    xy = model.vertex_xy0.copy()
    # collapse block 1's edge from (1, 1) to (0.5, 1.001): vertex 6 onto vertex 7
    first = model.vertex_offset[1]
    xy[first + 2] = xy[first + 3]
    stepper = Stepper(model)
    cint_k, length_k = detect_contacts(model, xy, stepper.buffers)
    cint_r, length_r = reference.detect_contacts(model, xy)
    assert np.array_equal(cint_k, cint_r)
    assert np.allclose(length_k, length_r, rtol=1e-12, atol=1e-15)
    assert np.all(np.isfinite(length_k))
    collapsed = first + 2
    assert not np.any(cint_k[:, 2] == collapsed)  # no contact against the collapsed edge


def test_vertex_near_a_corner_that_pairs_elsewhere_is_still_tested_against_the_edge():
    """A wedge's tip T lies on the other block's edge, 1.26 cm from that edge's end corner C
    (within the search distance), but C's nearest vertex of the wedge is the top of the wedge's
    1.22 cm end edge, not T. T's contact with the edge must be found (it was skipped as "near a
    corner" while the pair (C, T) was not handled as a vertex pair either)."""
    t = np.array([np.cos(np.radians(33.0)), np.sin(np.radians(33.0))])
    left = np.array([0.0, 0.3887])
    corner = left + 4.0 / t[0] * t            # C, end of the lower block's joint edge
    tip = corner - 0.0126 * t                  # T, on that edge
    scene = dd.Scene(gravity=9.81)
    scene.add_block([(0, 0), (corner[0], 0), corner, left], material=ROCK)                 # lower
    scene.add_block([left, tip, tip + (0.0, 0.0122), left + (0.0, 0.05)], material=ROCK)   # wedge
    scene.add_block([(-1, -1), (6, -1), (6, 0), (-1, 0)], material=ROCK, fixed=True)
    model = build_model(scene)
    xy = model.initial_state().vertex_xy
    # the model works about the domain's centre: move C and T with it
    shift = xy.mean(axis=0) - np.concatenate([b.vertices for b in scene.blocks]).mean(axis=0)
    corner, tip = corner + shift, tip + shift
    assert model.search_distance > 0.0126
    c_idx = int(np.argmin(np.linalg.norm(xy - corner, axis=1)))
    t_idx = int(np.argmin(np.linalg.norm(xy - tip, axis=1)))
    d_top = np.linalg.norm(xy - corner, axis=1)
    d_top[model.vertex_block != model.vertex_block[t_idx]] = np.inf
    assert int(np.argmin(d_top)) != t_idx  # the corner's nearest wedge vertex is not the tip
    edge = c_idx  # the lower block's joint edge starts at C (CCW: ..., C, left)
    for cint, _ in (detect_contacts(model, xy, _Buffers()), reference.detect_contacts(model, xy)):
        rows = {(int(r[1]), int(r[2])) for r in cint if r[0] == 0}
        assert (t_idx, edge) in rows


@pytest.mark.parametrize("kernels", ["taichi", "numpy"])
def test_pairs_kept_between_detections_find_the_contacts_of_a_fresh_broad_phase(kernels):
    """`contacts.PairList` (a Verlet list): the pairs found with a skin serve later detections
    while no vertex has moved half of it. A pile of blocks dropped from gaps of 2 cm that land,
    bounce and settle: at every step the contacts (kinds, vertices, edges, lengths) equal those
    of a fresh broad phase, on the kernel path and on its NumPy twin, and the pairs were both
    kept and found again over the run."""
    from scenes import stacked_grid
    from ddatai import vectorized

    scene, params = stacked_grid.build(n=4, gap=0.02)
    model = build_model(scene, dd.Params(kernels=kernels, initial_equilibrium=False, dt=2e-3))
    stepper = Stepper(model)
    pair_list = stepper.buffers.pair_list if kernels == "taichi" else stepper.narrow.pair_list
    fresh = (lambda xy: detect_contacts(model, xy, _Buffers())) if kernels == "taichi" else \
        (lambda xy: vectorized.detect_contacts(model, xy, None))
    state = model.initial_state()
    kept = found = 0
    for _ in range(80):
        before = pair_list.found_at
        cint, length = stepper.detect(state.vertex_xy)
        if pair_list.found_at is before:
            kept += 1
        else:
            found += 1
        fresh_cint, fresh_length = fresh(state.vertex_xy)
        np.testing.assert_array_equal(cint, fresh_cint)
        np.testing.assert_array_equal(length, fresh_length)
        state = stepper.advance(state).state
    assert kept >= 10 and found >= 3, (kept, found)


def test_numpy_path_detection_at_the_same_geometry_gives_the_same_contacts():
    """`Stepper.detect` on the NumPy path keeps its last answer for the same geometry (the
    equilibrium stage detects at one geometry up to three times in a row): the same contacts as
    a fresh detection, handed out as copies that a caller may change, and a moved geometry
    detected anew."""
    from ddatai import vectorized

    model = build_model(random_jointed_scene(3), dd.Params(kernels="numpy"))
    assert model.numpy_path
    stepper = Stepper(model)
    xy = perturbed_vertices(model, 3, shift=0.1 * model.search_distance)
    cint, length = stepper.detect(xy)
    assert len(length) > 0
    cint[:] = -1
    length[:] = 0.0  # a caller's edit does not reach the kept answer
    again, again_length = stepper.detect(xy.copy())
    fresh, fresh_length = vectorized.detect_contacts(model, xy, None)
    np.testing.assert_array_equal(again, fresh)
    np.testing.assert_array_equal(again_length, fresh_length)
    moved = xy.copy()
    moved[model.vertex_block == int(np.flatnonzero(~model.block_fixed)[0])] += 0.5 * model.search_distance
    np.testing.assert_array_equal(stepper.detect(moved)[0], vectorized.detect_contacts(model, moved, None)[0])


def test_a_copy_shares_the_geometry_and_owns_its_state():
    """`Contacts.copy`: the contacts' geometry (``contacts.GEOMETRY``: fixed during a step, written
    by no one) is shared, so the batched evaluations know a copy's contacts again
    (`ddatai.stage_batch_index`); every other array is the copy's own."""
    from ddatai.contacts import GEOMETRY

    model = build_model(random_jointed_scene(1))
    st, s = Stepper(model), model.initial_state()
    c = Contacts.start(model, s.vertex_xy, *st.detect(s.vertex_xy), ContactMemory.empty(), True)
    d = c.copy()
    for name, value in vars(c).items():
        if isinstance(value, np.ndarray):
            assert (getattr(d, name) is value) == (name in GEOMETRY), name
            np.testing.assert_array_equal(getattr(d, name), value)
    d.state[:] = ContactState.OPEN
    d.omega[:] += 1.0
    assert np.any(c.state != ContactState.OPEN) and not np.array_equal(c.omega, d.omega)
