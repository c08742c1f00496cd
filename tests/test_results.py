"""Results: frames, per-step records, polygons, contacts, and .npz round trip."""

import numpy as np

import ddatai as dd
from ddatai.results import STEP_PHASES
from cases import sliding_scene


def test_results_content_and_roundtrip(tmp_path):
    scene, block = sliding_scene(30.0, 20.0)
    idx = scene.add_measured_point(block, scene.polygon(block)[0])
    res = dd.simulate(scene, duration=0.2, record_every=5, record_contacts=True)
    nb = scene.n_blocks
    F = res.n_frames
    assert res.time[0] == 0.0 and res.time[-1] == 0.2
    assert res.centroid.shape == (F, nb, 2) and res.velocity.shape == (F, nb, 2)
    assert res.rotation.shape == (F, nb) and res.stress.shape == (F, nb, 3)
    assert len(res.steps) == 20 and F == 1 + 20 // 5
    for name in ("dt", "oc_iterations", "dt_cuts", "contacts", "max_penetration",
                 *(f"t_{phase}" for phase in STEP_PHASES)):
        assert name in res.steps.dtype.names
    assert np.all(res.steps["contacts"] == 2) and np.all(res.steps["dt"] > 0)
    # frame 0 is the initial geometry, in the user's coordinates
    assert np.allclose(res.polygons(0)[block], scene.polygon(block))
    # the measured point is the block's first vertex: it moves with it
    assert np.allclose(res.measured[:, idx], res.vertices[:, res.vertex_offset[block]])
    xy, st = res.contacts(-1)
    assert len(xy) == 2 and np.all(st == dd.ContactState.SLIDE)
    path = tmp_path / "run.npz"
    res.save(path)
    back = dd.load_results(path)
    for name in ("time", "centroid", "rotation", "velocity", "stress", "vertices", "steps",
                 "contact_xy", "contact_state", "measured"):
        assert np.array_equal(getattr(back, name), getattr(res, name))
    assert back.summary()["steps"] == 20
