"""Offscreen rendering: GIF frame count, size, frames that differ, determinism, PNG, labels."""

import numpy as np
import pytest

import ddatai as dd
from cases import sliding_scene


@pytest.fixture(scope="module")
def run():
    scene, block = sliding_scene(30.0, 20.0)
    return dd.simulate(scene, duration=0.3, record_contacts=True)


def test_gif_frames_size_and_motion(run, tmp_path):
    import imageio.v3 as iio

    path = dd.write_gif(run, tmp_path / "a.gif", size=(200, 150), stride=5, show_contacts=True)
    frames = iio.imread(path, index=None)
    expected = len(range(0, run.n_frames, 5)) + (0 if (run.n_frames - 1) % 5 == 0 else 1)
    assert frames.shape[0] == expected
    assert frames.shape[1:3] == (150, 200)
    assert not np.array_equal(frames[0], frames[-1])  # the block moved


def test_output_is_deterministic(run, tmp_path):
    a = dd.write_gif(run, tmp_path / "a.gif", size=(160, 120), stride=10)
    b = dd.write_gif(run, tmp_path / "b.gif", size=(160, 120), stride=10)
    assert a.read_bytes() == b.read_bytes()


def test_png_and_labels(run, tmp_path):
    from PIL import Image

    labels = np.full(run.n_blocks, -1)
    labels[1] = 0
    path = dd.write_png(run, tmp_path / "f.png", frame=-1, size=(220, 160), labels=labels,
                        label_names=["key group"], title="test")
    image = np.asarray(Image.open(path))
    assert image.shape == (160, 220, 3)
    # the labelled block's colour appears in the picture
    assert np.any(np.all(image == (31, 119, 180), axis=-1))


def test_view_is_fixed_across_frames(run):
    """The fixed base is drawn at the same pixels in every frame."""
    frames = dd.render_frames(run, size=(200, 150), frames=[0, run.n_frames - 1])
    grey = [np.all(f == (178, 178, 178), axis=-1) for f in frames]
    assert grey[0].sum() > 100
    assert (grey[0] & grey[1]).sum() > 0.95 * grey[0].sum()


def test_ten_thousand_blocks_render(tmp_path):
    """A frame with 10,000 blocks renders (timing is measured in benchmarks/render.py)."""
    from ddatai.results import Results

    n = 10_000
    k = 100
    i, j = np.meshgrid(np.arange(k), np.arange(k))
    corners = np.array([(0, 0), (0.9, 0), (0.9, 0.9), (0, 0.9)])
    verts = (np.stack([i.ravel(), j.ravel()], axis=1)[:, None, :] + corners[None]).reshape(-1, 2)
    res = Results(time=np.zeros(1), centroid=np.zeros((1, n, 2)), rotation=np.zeros((1, n)),
                  velocity=np.zeros((1, n, 2)), angular_velocity=np.zeros((1, n)),
                  stress=np.zeros((1, n, 3)), vertices=verts[None], vertex_offset=np.arange(0, 4 * n + 1, 4),
                  block_fixed=np.zeros(n, bool), measured=np.zeros((1, 0, 2)), contact_offset=np.zeros(2, int),
                  contact_xy=np.zeros((0, 2)), contact_state=np.zeros(0, np.int8),
                  steps=np.zeros(0, dd.STEP_DTYPE))
    frame = dd.render_frames(res, size=(640, 480))[0]
    assert frame.shape == (480, 640, 3)


@pytest.mark.parametrize("kwargs, message", [
    (dict(size=(10, 10)), "size"), (dict(fps=0), "fps"), (dict(stride=0), "stride"),
    (dict(labels=np.zeros(2)), "labels"),
])
def test_bad_render_arguments(run, tmp_path, kwargs, message):
    with pytest.raises(ValueError, match=message):
        dd.write_gif(run, tmp_path / "x.gif", **kwargs)
