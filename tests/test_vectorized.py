"""The vectorised NumPy detection and contact vectors (`ddatai.vectorized`) against the Taichi
kernel path (`ddatai.contacts.detect_contacts`, `kernels.contact_vectors`): the same candidate
pairs, the same contacts (kind, vertices, edges, lines) in the same order, the same lengths and
contact vectors to round-off, on random jointed scenes (convex, concave, with slivers) moved so
that they touch, penetrate and nearly tie, and on hand-made edge cases of Shi's rules
(docs/method/dda.md §3.3–3.6)."""

import warnings

import numpy as np
import pytest

import ddatai as dd
from cases import G, ROCK, perturbed_vertices, random_jointed_scene
from ddatai import vectorized
from ddatai.contacts import _Buffers, broad_phase, detect_contacts, edge_projection, narrow_phase
from ddatai.cutting import SliverWarning
from ddatai.layout import VE, VV
from ddatai.model import build_model

#: rigid moves of every block, as fractions of the search distance d0: 0 (the cut geometry:
#: coincident corners, the TIE rule), 1e-9 (round-off-sized moves: near-ties of every
#: comparison), 0.05 … 0.3 (touching, vertex-vertex, slightly open and penetrating contacts),
#: 1.0 (deep penetrations beyond d9 and wide gaps)
SHIFTS = (0.0, 1e-9, 0.05, 0.3, 1.0)


def _kernel_vectors(model, xy, cint, omega):
    from ddatai import kernels

    vec = np.zeros((len(cint), 6, 6))
    sca = np.zeros((len(cint), 3))
    centroid = np.ascontiguousarray(model.block_geometry(xy)["centroid"])
    if len(cint):
        kernels.contact_vectors(xy, model.vertex_block, model.vertex_next, centroid, cint, omega, vec, sca)
    return vec, sca


def _assert_same(model, xy, seed=0):
    """Vectorised path == kernel path: pairs, contacts and lengths, contact vectors."""
    d0 = model.search_distance
    buffers = _Buffers()
    for margin in (d0, 3.0 * d0):
        assert np.array_equal(vectorized.broad_phase(model, xy, margin),
                              broad_phase(model, xy, margin, buffers))
    cint_k, length_k = detect_contacts(model, xy, buffers)
    cint_v, length_v = vectorized.detect_contacts(model, xy)
    assert cint_v.dtype == np.int32 and cint_v.shape[1:] == (5,)
    assert np.array_equal(cint_v, cint_k)
    assert np.allclose(length_v, length_k, rtol=1e-12, atol=1e-12 * d0)
    # the narrow phase alone, on every box pair within a wider margin than the search distance
    pairs = vectorized.broad_phase(model, xy, 3.0 * d0)
    wide_k = narrow_phase(model, xy, pairs, buffers)
    wide_v = vectorized.narrow_phase(model, xy, pairs)
    assert np.array_equal(wide_v[0], wide_k[0])
    assert np.allclose(wide_v[1], wide_k[1], rtol=1e-12, atol=1e-12 * d0)
    # contact vectors with lock points anywhere on (and beyond) the reference line
    omega = np.random.default_rng(seed).uniform(-0.2, 1.2, len(cint_k))
    centroid = model.block_geometry(xy)["centroid"]
    vec_v, sca_v = vectorized.contact_vectors(model, xy, centroid, cint_k, omega)
    vec_k, sca_k = _kernel_vectors(model, xy, cint_k, omega)
    scale = max(1.0, float(np.abs(vec_k).max(initial=0.0)))
    assert np.allclose(vec_v, vec_k, rtol=1e-12, atol=1e-12 * scale)
    assert np.allclose(sca_v, sca_k, rtol=1e-12, atol=1e-12 * d0)
    return cint_k


def _zigzag_scene(seed):
    """A 10 m square cut by random bent joints (polylines with two kinks): concave blocks."""
    rng = np.random.default_rng(seed)
    scene = dd.Scene(gravity=G)
    joints = []
    for _ in range(rng.integers(2, 5)):
        p = rng.uniform(2, 8, 2)
        ang = rng.uniform(0, np.pi)
        t = np.array([np.cos(ang), np.sin(ang)])
        n = np.array([-t[1], t[0]])
        kinks = [p - rng.uniform(1, 3) * t + rng.uniform(-1.5, 1.5) * n,
                 p + rng.uniform(1, 3) * t + rng.uniform(-1.5, 1.5) * n]
        joints.append(([p - 20 * t, kinks[0], p, kinks[1], p + 20 * t],
                       dd.Joint(friction=float(rng.uniform(10, 40)))))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SliverWarning)
        ids = scene.cut([(0, 0), (10, 0), (10, 10), (0, 10)], joints, material=ROCK)
    scene.set_fixed(ids[0])
    return scene


def _sliver_scene(seed, slivers):
    """Random persistent joints plus two nearly coinciding ones (a 1:100 sliver, or, merged,
    a concave block)."""
    rng = np.random.default_rng(seed)
    scene = dd.Scene(gravity=G)
    ang = rng.uniform(0, np.pi)
    t = 20 * np.array([np.cos(ang), np.sin(ang)])
    n = np.array([-t[1], t[0]]) / 20
    p = rng.uniform(3, 7, 2)
    joints = [([p - t, p + t], dd.Joint(friction=30.0)),
              ([p + 0.05 * n - t, p + 0.05 * n + t], dd.Joint(friction=30.0))]
    for _ in range(rng.integers(2, 5)):
        q = rng.uniform(0, 10, 2)
        a = rng.uniform(0, np.pi)
        d = 20 * np.array([np.cos(a), np.sin(a)])
        joints.append(([q - d, q + d], dd.Joint(friction=25.0)))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SliverWarning)
        ids = scene.cut([(0, 0), (10, 0), (10, 10), (0, 10)], joints, material=ROCK, slivers=slivers)
    scene.set_fixed(ids[0])
    return scene


def _moved(model, seed, shift):
    return model.vertex_xy0.copy() if shift == 0 else \
        perturbed_vertices(model, seed, shift=shift * model.search_distance,
                           angle=min(0.002, 10 * shift * model.search_distance))


def _kinds(cint, model):
    """(VE from the vertex of the lower block, VE from the higher, VV) counts."""
    ve = cint[:, 0] == VE
    low = model.vertex_block[cint[:, 1]] < model.vertex_block[cint[:, 2]]
    return int((ve & low).sum()), int((ve & ~low).sum()), int((cint[:, 0] == VV).sum())


@pytest.mark.parametrize("seed", range(8))
def test_random_jointed_scenes_match_the_kernels(seed):
    model = build_model(random_jointed_scene(seed))
    found = np.zeros(3, int)
    for k, shift in enumerate(SHIFTS):
        cint = _assert_same(model, _moved(model, 50 + seed + k, shift), seed)
        found += _kinds(cint, model)
    assert found.min() > 0  # both sides' vertices and vertex-vertex contacts were compared


@pytest.mark.parametrize("seed", range(6))
def test_concave_blocks_match_the_kernels(seed):
    model = build_model(_zigzag_scene(seed))
    xy0 = model.vertex_xy0
    prv, nxt = model.vertex_prev, model.vertex_next
    r1, r2 = xy0[nxt] - xy0, xy0[prv] - xy0
    assert (r1[:, 0] * r2[:, 1] - r1[:, 1] * r2[:, 0] < 0).any()  # concave vertices
    for k, shift in enumerate(SHIFTS):
        _assert_same(model, _moved(model, 70 + seed + k, shift), seed)


@pytest.mark.parametrize("slivers", ["warn", "merge"])
@pytest.mark.parametrize("seed", range(3))
def test_scenes_with_slivers_match_the_kernels(seed, slivers):
    model = build_model(_sliver_scene(seed, slivers))
    for k, shift in enumerate(SHIFTS):
        _assert_same(model, _moved(model, 90 + seed + k, shift), seed)


def _model(*blocks, fixed=(0,), params=None):
    scene = dd.Scene()
    for k, b in enumerate(blocks):
        scene.add_block(b, material=ROCK, fixed=k in fixed)
    return build_model(scene, params or dd.Params())


def test_a_single_block_has_no_pairs_and_no_contacts():
    model = _model([(0, 0), (1, 0), (1, 1), (0, 1)], fixed=())
    xy = model.vertex_xy0
    assert vectorized.broad_phase(model, xy, model.search_distance).shape == (0, 2)
    cint, length = vectorized.detect_contacts(model, xy)
    assert cint.shape == (0, 5) and length.shape == (0,)
    vec, sca = vectorized.contact_vectors(model, xy, model.block_geometry(xy)["centroid"], cint, np.zeros(0))
    assert vec.shape == (0, 6, 6) and sca.shape == (0, 3)
    _assert_same(model, xy)


def test_no_contacts_far_apart_or_with_overlapping_boxes():
    """Blocks apart: no pair. Two triangles whose boxes overlap but that are 0.5 m apart: a
    pair, no contact. Both fixed and touching: no pair."""
    model = _model([(0, 0), (1, 0), (0, 1)], [(5, 5), (6, 5), (6, 6)], fixed=())
    assert len(vectorized.broad_phase(model, model.vertex_xy0, model.search_distance)) == 0
    model = _model([(0, 0), (2, 0), (0, 2)], [(2, 1.5), (2, 3), (0.5, 3)], fixed=())
    xy = model.vertex_xy0
    assert len(vectorized.broad_phase(model, xy, model.search_distance)) == 1
    assert len(vectorized.detect_contacts(model, xy)[0]) == 0
    _assert_same(model, xy)
    model = _model([(0, 0), (1, 0), (1, 1), (0, 1)], [(1, 0), (2, 0), (2, 1), (1, 1)], fixed=(0, 1))
    assert len(vectorized.broad_phase(model, model.vertex_xy0, model.search_distance)) == 0


@pytest.mark.parametrize("gap", [1e-4, 0.0, -1e-4])
def test_two_blocks_corner_to_corner(gap):
    """Two squares meeting at their corners (apart, touching, overlapping): one vertex-vertex
    contact whose lines are the edges across the smaller free gap (§3.4)."""
    model = _model([(-1, -1), (0, -1), (0, 0), (-1, 0)], [(1e-4, 1e-4), (1, 1e-4), (1, 1), (1e-4, 1)])
    xy = model.vertex_xy0.copy()
    xy[model.vertex_block == 1] += gap - 1e-4
    cint = _assert_same(model, xy)
    assert len(cint) == 1 and cint[0, 0] == VV
    # B turned so that the gap on one side is clearly smaller: each pair of lines in turn
    lines = set()
    for turn in (0.3, -0.3):
        c, s = np.cos(turn), np.sin(turn)
        sq = [(1e-4 + c * x - s * y, 1e-4 + s * x + c * y) for x, y in [(0, 0), (1, 0), (1, 1), (0, 1)]]
        model = _model([(-1, -1), (0, -1), (0, 0), (-1, 0)], sq)
        xy = model.vertex_xy0.copy()
        xy[model.vertex_block == 1] += gap - 1e-4
        cint = _assert_same(model, xy)
        assert len(cint) == 1 and cint[0, 0] == VV
        lines.add(cint[0, 1] == cint[0, 4])  # edge1 == vertex0: the lines across the gap e6
    assert len(lines) == 2


def test_concave_corner_both_ways():
    """A square's corner in the concave corner of an L-shaped block: the convex vertex against
    both edges of the concave one, whichever block comes first."""
    L = [(0, 0), (3, 0), (3, 1), (1, 1), (1, 3), (0, 3)]
    sq = [(1 + 1e-4, 1 + 1e-4), (2, 1 + 1e-4), (2, 2), (1 + 1e-4, 2)]
    for blocks in ((L, sq), (sq, L)):
        model = _model(*blocks, fixed=())
        cint = _assert_same(model, model.vertex_xy0)
        assert (cint[:, 0] == VE).sum() >= 2


def _x_junction(slide):
    """Four unit squares meeting at one point (blocks 0, 1 below, 2, 3 above), the upper row
    slid along the joint by ``slide``."""
    squares = [[(x, y), (x + 1, y), (x + 1, y + 1), (x, y + 1)] for y in (0, 1) for x in (0, 1)]
    model = _model(*squares, fixed=())
    xy = model.vertex_xy0.copy()
    xy[model.vertex_block >= 2, 0] += slide
    return model, xy


#: where the TIE rule flips: block 2's corner lies inside block 0's top edge by s while block
#: 0's corner lies outside block 2's edge by s, so A's vertex is kept while −s ≥ s − TIE
TIE_FLIP = 0.5e-3


@pytest.mark.parametrize("slide", [0.0, 0.25e-3, 0.9999 * TIE_FLIP, 1.0001 * TIE_FLIP, 2e-3,
                                   -0.9999 * TIE_FLIP, -1.0001 * TIE_FLIP])
def test_x_junction_of_four_aligned_blocks(slide):
    """Each side-neighbour pair has coincident (or nearly coincident) corners on parallel
    edges: edge-edge contacts whose vertex the TIE rule picks (§3.4); the diagonal pairs meet
    corner to corner (vertex-vertex). The slides straddle the TIE rule's switch."""
    model, xy = _x_junction(slide)
    cint = _assert_same(model, xy)
    assert (cint[:, 0] == VV).sum() == 2  # the two diagonal pairs
    assert (cint[:, 0] == VE).sum() == 8  # two per side-neighbour pair


def test_x_junction_tie_flips_with_the_slide():
    """Between blocks 0 and 2, block 0 keeps the contact vertex at the left end of their
    joint while the upper block has slid less than TIE/2, and hands it to block 2 beyond."""
    owners = []
    for slide in (0.9999 * TIE_FLIP, 1.0001 * TIE_FLIP):
        model, xy = _x_junction(slide)
        cint = _assert_same(model, xy)
        b = model.vertex_block
        pair = ((b[cint[:, 1]] == 0) & (b[cint[:, 2]] == 2)) | ((b[cint[:, 1]] == 2) & (b[cint[:, 2]] == 0))
        owners.append(sorted(b[cint[pair, 1]].tolist()))
    assert owners == [[0, 0], [0, 2]]


def test_equidistant_vertices_take_the_lowest_index():
    """A triangle's apex exactly as far from two vertices of the other block (dyadic
    coordinates, exact): the lower-index one is its nearest; the other is tested against the
    edges (§3.3)."""
    params = dd.Params(max_displacement_ratio=0.05)
    model = _model([(-1, -1), (1, -1), (0, 0)], [(-1 / 32, 1 / 64), (1 / 32, 1 / 64), (0, 1)],
                   fixed=(), params=params)
    xy = model.vertex_xy0
    apex = 2
    q1, q2 = model.vertex_offset[1], model.vertex_offset[1] + 1
    d1, d2 = (np.sqrt(((xy[q] - xy[apex]) ** 2).sum()) for q in (q1, q2))
    assert d1 == d2 < model.search_distance
    cint = _assert_same(model, xy)
    assert len(cint) > 0


def test_vertices_exactly_d0_apart_are_a_close_pair():
    """The search distance is inclusive: two corners exactly d0 apart (side by side, their
    edges on one line) go through the vertex-pair rules and make a vertex-vertex contact; as
    vertex-edge candidates they would project off each other's edges and give none."""
    model = _model([(-1, -1), (0, -1), (0, 0), (-1, 0)], [(0.5, 0), (1.5, 0), (1.5, 1), (0.5, 1)])
    xy = model.vertex_xy0.copy()
    d0 = model.search_distance
    a, b = model.vertex_block == 0, model.vertex_block == 1
    xy[a] -= xy[model.vertex_offset[0] + 2]      # A's top right corner at (0, 0) exactly
    xy[b] -= xy[model.vertex_offset[1]]          # B's bottom left corner at (0, 0) ...
    xy[b, 0] += d0                               # ... then at (d0, 0): exactly d0 away
    assert np.sqrt(((xy[model.vertex_offset[1]] - xy[model.vertex_offset[0] + 2]) ** 2).sum()) == d0
    cint = _assert_same(model, xy)
    assert len(cint) == 1 and cint[0, 0] == VV


def test_constants_agree_with_the_kernels():
    from ddatai import kernels, narrow, reference

    assert vectorized.EDGE_FLOOR == kernels.EDGE_FLOOR
    assert vectorized.TIE == kernels.TIE
    assert vectorized.SLACK == kernels.SLACK == reference.SLACK
    assert narrow.PASSED_DEPTH == kernels.PASSED_DEPTH == reference.PASSED_DEPTH
    assert vectorized.TWO_PI == kernels.TWO_PI


def test_grid_model_matches_the_kernels():
    """The benchmark's grid (benchmarks/detection.py): aligned blocks on a base, at rest and
    moved."""
    scene = dd.Scene(gravity=G)
    scene.add_block([(-1, -1), (7, -1), (7, 0), (-1, 0)], material=ROCK, fixed=True)
    for j in range(6):
        for i in range(6):
            scene.add_block([(i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1)], material=ROCK)
    model = build_model(scene)
    for k, shift in enumerate(SHIFTS):
        _assert_same(model, _moved(model, k, shift), k)
    # the lock position of a fresh contact: its vertex's projection on the reference line
    xy = model.vertex_xy0
    cint, _ = vectorized.detect_contacts(model, xy)
    omega = edge_projection(xy, model.vertex_next, cint[:, 1], cint[:, 2])
    _, sca = vectorized.contact_vectors(model, xy, model.block_geometry(xy)["centroid"], cint, omega)
    ve = cint[:, 0] == VE
    assert np.allclose(sca[ve, 2], 0.0, atol=1e-12)  # ds0 = 0 at the lock point (§2.8.3)


def _passed_corners(depth, slide=2e-3, turn=0.2):
    """The four squares of `_x_junction` (unit squares), the upper row slid left by ``slide``
    along the joint and the upper right block (3) turned by ``turn`` degrees about its lower
    left corner Q, which then lies ``depth`` behind the top edge of the lower left block (0),
    ``slide`` past that block's corner P; the upper left block (2) slid 0.01 further, clear of
    block 3's turned edge. Returns the model, the vertices and (P, Q)."""
    model, xy = _x_junction(0.0)
    b = model.vertex_block
    q = int(model.vertex_offset[3])
    xy[b == 2, 0] -= slide + 0.01
    xy[b == 3, 0] -= slide
    xy[b == 3, 1] -= depth
    c, s = np.cos(np.radians(turn)), np.sin(np.radians(turn))
    rel = xy[b == 3] - xy[q]
    xy[b == 3] = xy[q] + np.stack([c * rel[:, 0] - s * rel[:, 1], s * rel[:, 0] + c * rel[:, 1]], axis=1)
    return model, xy, int(model.vertex_offset[0]) + 2, q


@pytest.mark.parametrize("depth", [1e-6, 1e-4])
def test_corners_of_diagonal_blocks_that_passed_each_other_are_vertex_edge_contacts(depth):
    """Where four squares meet and the upper row has slid along the joint, the diagonal blocks'
    corners P (block 0) and Q (block 3) have passed each other: Q lies on block 0's top edge,
    P under block 3's bottom edge. They are mutual nearest (2 mm apart, d0 = 12.5 mm), and a
    vertex-vertex contact acts on one line only: the lines across the smaller gap (block 3
    turned 0.2°, less than h1/2) were P against block 3's bottom edge and Q against block 0's
    right edge, 2 mm behind it, so Q sank unresisted into block 0's top edge; the pair's lines
    changed as the block turned on, and that depth was pushed out in one step (a square of a
    toppling stack thrown at 0.08 m/s, 30 g·Δt, docs/method/dda.md §3.4). Q, past P along
    block 0's top edge by more than TIE of it, within h1 of its line and deeper behind it than
    PASSED_DEPTH × d9, now sends the pair to the vertex-edge rules:
    Q against block 0's top edge and P against block 3's bottom edge, the same in the three
    implementations."""
    from ddatai import kernels, reference

    model, xy, P, Q = _passed_corners(depth)
    assert np.hypot(*(xy[P] - xy[Q])) < model.search_distance
    assert depth > kernels.PASSED_DEPTH * model.max_penetration
    cint = _assert_same(model, xy)
    cint_r, _ = reference.detect_contacts(model, xy)
    assert sorted(map(tuple, cint_r.tolist())) == sorted(map(tuple, cint.tolist()))
    b = model.vertex_block
    diagonal = {tuple(r) for r in cint.tolist() if {b[r[1]], b[r[2]]} == {0, 3}}
    top_of_0, bottom_of_3 = P, Q  # block 0's edge (P, next P) is its top edge; block 3's (Q, next Q) its bottom
    assert diagonal == {(VE, Q, top_of_0, -1, -1), (VE, P, bottom_of_3, -1, -1)}


def test_corners_of_diagonal_blocks_touching_to_round_off_stay_a_vertex_vertex_contact():
    """The same corners with Q on block 0's top edge to within PASSED_DEPTH × d9 (the elastic
    settlement of an X-junction at rest, 1e-11–1e-10 m): one vertex-vertex contact, as before,
    so that an X-junction at rest does not flip between representations step by step."""
    model, xy, P, Q = _passed_corners(1e-12)
    cint = _assert_same(model, xy)
    b = model.vertex_block
    diagonal = [r for r in cint.tolist() if {b[r[1]], b[r[2]]} == {0, 3}]
    assert len(diagonal) == 1 and diagonal[0][0] == VV


def _last_keys(model, cint):
    """The sorted contact keys (``ContactMemory.key``) of a step whose contacts were ``cint``."""
    from ddatai.contacts import contact_keys

    return np.sort(contact_keys(cint, model.n_vertices))


@pytest.mark.parametrize("depth", [1e-12, 0.0])
def test_a_corner_pair_handed_to_the_vertex_edge_rules_stays_handed_while_a_vertex_lies_past_its_partner(depth):
    """The persistent hand-over (docs/method/dda.md §3.4). The passed corners, handed to the
    vertex-edge rules at 1e-4 deep, then pushed out by their vertex-edge contact to within
    PASSED_DEPTH × d9 of the edge (1e-12 behind it) or onto its line: read without memory
    they are one vertex-vertex contact again (and were, every other step: 2,018 hand-overs in
    1,057 of the 1,319 steps of the 4-5-6-7 stack's slow ramp at 18°), but with the last step's
    contacts' keys (``narrow_phase``'s ``last_keys``) the pair keeps its two vertex-edge
    contacts while Q lies past P along block 0's top edge. A pair whose last contact was
    vertex-vertex (an X-junction at rest) is read as before."""
    model, xy_deep, P, Q = _passed_corners(1e-4)
    before, _ = vectorized.detect_contacts(model, xy_deep)
    handed = _last_keys(model, before)
    _, xy, _, _ = _passed_corners(depth)
    b = model.vertex_block
    cint, _ = vectorized.detect_contacts(model, xy)
    assert [r[0] for r in cint.tolist() if {b[r[1]], b[r[2]]} == {0, 3}] == [VV]
    cint, _ = vectorized.detect_contacts(model, xy, None, handed)
    diagonal = {tuple(r) for r in cint.tolist() if {b[r[1]], b[r[2]]} == {0, 3}}
    assert diagonal == {(VE, Q, P, -1, -1), (VE, P, Q, -1, -1)}
    # an X-junction whose pair was a vertex-vertex contact last step stays one
    _, rest, _, _ = _passed_corners(1e-12)
    vv_keys = _last_keys(model, vectorized.detect_contacts(model, rest)[0])
    cint, _ = vectorized.detect_contacts(model, rest, None, vv_keys)
    assert [r[0] for r in cint.tolist() if {b[r[1]], b[r[2]]} == {0, 3}] == [VV]
    # and the hand-over ends once neither vertex lies past its partner (the rows slid back)
    _, back, _, _ = _passed_corners(1e-12, slide=-2e-3)
    cint, _ = vectorized.detect_contacts(model, back, None, handed)
    assert not {tuple(r) for r in cint.tolist()} & {(VE, Q, P, -1, -1), (VE, P, Q, -1, -1)}
    # or once the vertices are clear of the edges' lines (0.1 µm: the block lifted off; a
    # hand-over kept there held an open contact at an edge's end, ntdda's push block)
    _, clear, _, _ = _passed_corners(-1e-7)
    cint, _ = vectorized.detect_contacts(model, clear, None, handed)
    assert [r[0] for r in cint.tolist() if {b[r[1]], b[r[2]]} == {0, 3}] == [VV]


def test_an_open_corner_contact_carries_no_normal_force_from_a_line_it_does_not_use():
    """The passed corners slid the other way (the upper row 2 mm to the right, block 3 turned
    0.2°): a new vertex-vertex contact whose line 0 (P against block 3's bottom edge) lies 7 µm
    deep and whose line 1 (Q against block 0's right edge) 2 mm clear. It starts on the less
    penetrated line, open, and the start penetration that sets its normal force is that line's:
    none. (It took line 0's: p × 7 µm = 1.7e6 N/m; a corner 0.75 mm past the other's edge carried
    ~1e7 N/m while open, docs/method/dda.md §2.8.7.) And the judgement of a solve in which the
    law opens a VV contact leaves it no normal force from an earlier solve."""
    from types import SimpleNamespace

    from ddatai.contact_law import judge
    from ddatai.contacts import Contacts
    from ddatai.layout import OPEN
    from ddatai.model import ContactMemory

    model, xy, P, Q = _passed_corners(1e-12, -2e-3)
    cint, length = vectorized.detect_contacts(model, xy)
    c = Contacts.start(model, xy, cint, length, ContactMemory.empty(), False)
    k = np.flatnonzero((cint[:, 0] == VV) & (cint[:, 1] == P) & (cint[:, 3] == Q))
    assert len(k) == 1
    assert c.line[k[0]] == 1 and c.state[k[0]] == OPEN and c.normal_force[k[0]] == 0.0
    # an earlier solve's force on the open VV contact, and on an open VE contact
    c.normal_force[:] = 1e7
    m = c.n
    zeros = np.zeros(m)
    law = SimpleNamespace(dn=np.full(m, 1e-3), ds=zeros, line=c.line.copy(), closed=np.zeros(m, bool),
                          state=np.full(m, OPEN, np.int8), direction=np.ones(m, np.int8), fn=zeros, ft=zeros,
                          strength=zeros, dn_now=np.full(m, 1e-3), fn_now=zeros, ft_now=zeros, friction_now=zeros,
                          energy=0.0, tan_phi=None)
    judge(model, c, law, np.zeros(m, bool))
    vv = cint[:, 0] == VV
    assert np.all(c.normal_force[vv] == 0.0)
