"""A large model's return-mapping iterate skips what provably stays (`ddatai.iterate_skips`): the
line search with the contacts that keep their state along the step summed once, against the
reference bisection (`return_steps.line_search`), and the far blocks found by a bound of each
block's vertex displacements (docs/method/dda.md §5.3) against the vertex-by-vertex measure."""

import math

import numpy as np

import ddatai as dd
from ddatai import iterate_skips, return_mapping, return_steps
from ddatai.kinematics import block_displacement, move_points
from ddatai.return_steps import LINE_SEARCH_BISECTIONS


def _slope():
    """A 60° slope cut by two joint sets (~40 blocks), its base and back fixed."""
    rock = dd.Material(density=2600.0, young=10e9, poisson=0.25)
    scene = dd.Scene(gravity=9.81)
    height = 12.0
    crest = (4.0 + height / math.tan(math.radians(60.0)), height)
    outline = [(0.0, -3.0), (24.0, -3.0), (24.0, height), crest, (4.0, 0.0), (0.0, 0.0)]
    sets = [dd.JointSet(dip=35.0, spacing=2.5, joint=dd.Joint(friction=28.0)),
            dd.JointSet(dip=105.0, spacing=2.5, joint=dd.Joint(friction=35.0))]
    ids = scene.cut(outline, dd.joint_sets(outline, sets, seed=1), material=rock, slivers="merge")
    for b in ids:
        c = scene.polygon(b).mean(axis=0)
        if c[1] < 0.0 or c[0] > 20.0:
            scene.set_fixed(b)
    return scene, dd.Params(dt=1e-3)


def test_skips_match_the_reference_on_a_slopes_stage(monkeypatch):
    """Every line search of the stage gives the reference's α to the bisection's resolution
    (2⁻³⁰ of the step) and every far-block test the measured set; the stage ends with the same
    held, released and in-doubt blocks as the reference path."""
    scene, params = _slope()
    reference = dd.simulate(scene, params, steps=1).start[0]
    monkeypatch.setattr(return_mapping, "LOWRANK_UNKNOWNS", 0)  # the large models' path on a small one
    searched, far_tests = [], [0]
    skipped_search, far_call = iterate_skips.LineSearch.__call__, iterate_skips.FarBlocks.__call__

    def search(self, *args):
        alpha = skipped_search(self, *args)
        searched.append((alpha, return_steps.line_search(*args)))
        return alpha

    def far(self, disp, movable, far_at):
        found = far_call(self, disp, movable, far_at)
        measured = movable & (block_displacement(self.model, self.vertex_xy, self.geom, disp) > far_at)
        assert np.array_equal(found, measured)
        far_tests[0] += 1
        return found

    monkeypatch.setattr(iterate_skips.LineSearch, "__call__", search)
    monkeypatch.setattr(iterate_skips.FarBlocks, "__call__", far)
    skipped = dd.simulate(scene, params, steps=1).start[0]
    alphas = np.array(searched)
    assert len(alphas) and np.count_nonzero(alphas[:, 1] < 1.0)  # the bisection ran
    assert np.abs(alphas[:, 0] - alphas[:, 1]).max() <= 1.0 / 2 ** LINE_SEARCH_BISECTIONS
    assert far_tests[0] > 0
    for name in ("held", "released", "in_doubt", "welded"):
        assert skipped[name] == reference[name], name


def test_displacement_bound_holds_for_large_motions():
    """The bound |(u₀, v₀)| + ρ·(|r₀| + ‖ε‖) is at least every vertex's exact-rotation
    displacement (`kinematics.move_points`), for rotations up to a radian and strains of 10 %."""
    rng = np.random.default_rng(3)
    xy = rng.uniform(-5.0, 5.0, (40, 2)) + 100.0
    block = np.repeat(np.arange(10), 4)
    centroid = np.array([xy[block == b].mean(axis=0) for b in range(10)])
    radius = np.array([np.hypot(*(xy[block == b] - centroid[b]).T).max() for b in range(10)])
    for _ in range(200):
        d = rng.normal(size=(10, 6)) * [1.0, 1.0, 0.5, 0.05, 0.05, 0.05]
        moved = np.hypot(*(move_points(xy, block, centroid, d) - xy).T)
        exact = np.maximum.reduceat(moved, np.arange(0, 40, 4))
        bound = iterate_skips.displacement_bound(d, radius)
        assert (exact <= bound * (1.0 + iterate_skips.BOUND_MARGIN) + 1e-12).all()
