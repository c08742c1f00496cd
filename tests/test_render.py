"""Offscreen rendering: GIF frame count, size, frames that differ, determinism, PNG, labels."""

import importlib.util

import numpy as np
import pytest

import ddatai as dd
from cases import sliding_scene

SLIDING = str(__import__("pathlib").Path(__file__).resolve().parents[1] / "scenes" / "sliding_block.py")


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


def _moving_square(time):
    """Results of one square moving right at 1 m/s over the given frame times (no simulation)."""
    from ddatai.results import Results

    time = np.asarray(time, float)
    n = len(time)
    square = np.array([(0, 0), (1, 0), (1, 1), (0, 1)], float)
    ground = np.array([(-1, -1), (12, -1), (12, 0), (-1, 0)], float)
    verts = np.stack([np.concatenate([ground, square + (t, 0.0)]) for t in time])
    centroid = np.stack([[(5.5, -0.5), (0.5 + t, 0.5)] for t in time])
    velocity = np.zeros((n, 2, 2))
    velocity[:, 1, 0] = 1.0
    return Results(time=time, centroid=centroid, rotation=np.zeros((n, 2)), velocity=velocity,
                   angular_velocity=np.zeros((n, 2)), stress=np.zeros((n, 2, 3)), vertices=verts,
                   vertex_offset=np.array([0, 4, 8]), block_fixed=np.array([True, False]),
                   measured=np.zeros((n, 0, 2)), contact_offset=np.zeros(n + 1, np.int64),
                   contact_xy=np.zeros((0, 2)), contact_state=np.zeros(0, np.int8),
                   steps=np.zeros(0, dd.STEP_DTYPE))


def _gif_durations(path):
    from PIL import Image

    with Image.open(path) as im:
        out = []
        for k in range(im.n_frames):
            im.seek(k)
            out.append(im.info["duration"] / 1000.0)
    return out


def test_long_gif_is_streamed_in_bounded_memory(tmp_path, monkeypatch):
    """Drawing every one of 600 frames: at no time are more than a few frames alive, and the
    file grows while frames are still being drawn (each frame reaches the writer and the disk
    as it is drawn, none is kept)."""
    import weakref

    from ddatai import render

    res = _moving_square(np.linspace(0.0, 10.0, 600))
    path = tmp_path / "long.gif"
    refs: list = []
    most, sizes = [0], []
    original = render.painter._Painter.image

    class Frame(np.ndarray):  # a plain ndarray cannot be weakly referenced
        pass

    def image(self, frame):
        most[0] = max(most[0], sum(r() is not None for r in refs))
        sizes.append(path.stat().st_size if path.exists() else 0)
        out = original(self, frame).view(Frame)
        refs.append(weakref.ref(out))
        return out

    monkeypatch.setattr(render.painter._Painter, "image", image)
    dd.write_gif(res, path, size=(64, 64), stride=1)
    assert len(sizes) == 600
    assert most[0] <= 3, f"{most[0]} frames alive at once"
    assert 0 < sizes[300] < sizes[-1] < path.stat().st_size


def test_gif_plays_at_the_stated_speed_whatever_the_time_steps(tmp_path):
    """Frames recorded at uneven steps (Δt cut to a tenth in the middle): the GIF samples
    simulated time evenly, so it plays for duration / speed seconds."""
    time = np.concatenate([np.arange(0, 1.0, 0.01), np.arange(1.0, 1.5, 0.001), np.arange(1.5, 3.0001, 0.01)])
    res = _moving_square(time)
    for speed, fps in ((1.0, 20.0), (0.5, 20.0), (2.0, 30.0)):
        path = dd.write_gif(res, tmp_path / f"s{speed}.gif", size=(64, 64), fps=fps, speed=speed)
        durations = _gif_durations(path)
        assert abs(sum(durations) - 3.0 / speed) <= 1.0 / fps + 0.01
        assert len(durations) == round(3.0 / speed * fps) + 1
    # the old way: one GIF frame per recorded frame, the cut stretch plays ten times slower
    path = dd.write_gif(res, tmp_path / "stride.gif", size=(64, 64), stride=1)
    assert len(_gif_durations(path)) == len(time)


def test_gif_schedule_picks_the_nearest_frame_and_merges_repeats():
    from ddatai.render import gif_schedule

    frames, durations = gif_schedule(np.array([0.0, 0.04, 0.3, 0.31, 1.0]), fps=10.0, speed=1.0)
    # targets 0, 0.1, ..., 1.0: 0.1 -> 0.04, 0.2 -> 0.3 (nearer than 0.04), 0.3 -> 0.3, 0.4-0.6 -> 0.31, 0.7-1.0 -> 1.0
    assert frames == [0, 1, 2, 3, 4]
    assert durations == [0.1, 0.1, 0.2, 0.3, 0.4]
    # fps that does not divide 100: hundredths that add up without drift
    frames, durations = gif_schedule(np.linspace(0, 3, 301), fps=30.0, speed=1.0)
    assert len(frames) == 91 and abs(sum(durations) - 91 / 30) < 0.006
    assert set(durations) <= {0.03, 0.04}


def test_gif_frames_read_back_exactly(run, tmp_path):
    """Every frame reaches the file unchanged (each with its own colour table), also small
    frames of few colours, and any GIF reader decodes the file."""
    import imageio.v3 as iio

    for size in ((200, 150), (64, 64)):
        path = dd.write_gif(run, tmp_path / "exact.gif", size=size, stride=7, show_contacts=True)
        drawn = dd.render_frames(run, size=size, stride=7, show_contacts=True)
        back = iio.imread(path, index=None)
        assert back.shape == (len(drawn), size[1], size[0], 3)
        for a, b in zip(back, drawn):
            assert np.array_equal(a, b)


def _static_pair():
    """A square that moves 2 m with zero recorded velocity (a static run) on a fixed ground,
    and a measured point at its centre."""
    res = _moving_square(np.array([0.0, 1.0, 2.0]))
    res.velocity[:] = 0.0
    res.measured = res.centroid[:, 1:2].copy()
    return res


def test_static_run_is_coloured_by_displacement():
    """With every speed below 1 mm/s a speed scale would paint one colour; the picture colours
    blocks by how far they have moved instead (frame 0: not yet; frame 2: the most)."""
    from ddatai import render

    res = _static_pair()
    painter = render.painter._Painter(res, [0, 1, 2], size=(200, 150), labels=None, label_names=None,
                              show_contacts=False, title=None, max_speed=None)
    assert painter.quantity == "displacement" and painter.max_speed == pytest.approx(2.0)
    first, last = painter.block_colours(0)[1], painter.block_colours(2)[1]
    assert first == render.SPEED_COLOURS[0] and last == render.SPEED_COLOURS[-1]
    # with a speed scale given explicitly, speed it is
    painter = render.painter._Painter(res, [0, 2], size=(200, 150), labels=None, label_names=None,
                              show_contacts=False, title=None, max_speed=1.0)
    assert painter.quantity == "speed" and painter.block_colours(2)[1] == render.SPEED_COLOURS[0]


def test_measured_points_are_drawn():
    from ddatai import render

    res = _static_pair()
    frame = dd.render_frames(res, size=(200, 150), frames=[2])[0]
    assert np.any(np.all(frame == render.MEASURED, axis=-1))
    res.measured = np.zeros((3, 0, 2))
    frame = dd.render_frames(res, size=(200, 150), frames=[2])[0]
    assert not np.any(np.all(frame == render.MEASURED, axis=-1))


def _ink_box(image: np.ndarray):
    """(left, top, right, bottom) of the pixels that are not background, or None."""
    from ddatai import render

    ink = np.any(image != render.BACKGROUND, axis=2)
    rows, cols = np.flatnonzero(ink.any(axis=1)), np.flatnonzero(ink.any(axis=0))
    if not len(rows):
        return None
    return int(cols[0]), int(rows[0]), int(cols[-1]) + 1, int(rows[-1]) + 1


LONG_TITLE = "Example II, key group {P, A}: rigid FS 1.586, Sarma FS 0.771, DDA FS 0.971 - the group slides out"


@pytest.mark.parametrize("size", [(320, 240), (1280, 720)])
@pytest.mark.parametrize("title", ["jointed_slope", "bolted_slope: design", LONG_TITLE, None])
@pytest.mark.parametrize("colouring", ["speed", "displacement", "labels"])
def test_title_time_and_colour_bar_never_overlap(size, title, colouring):
    """The header's parts are drawn one at a time on blank frames, over every frame of the
    animation (the time stamp changes); their measured ink boxes lie inside the picture and
    no two overlap (the gallery once printed "jointed_slope" over the colour bar's "speed").
    Nothing else is drawn in the header, and the model is drawn below it."""
    from PIL import Image, ImageDraw

    from ddatai import render

    res = _static_pair() if colouring == "displacement" else _moving_square(np.linspace(0.0, 12.0, 7))
    labels = np.array([-1, 0]) if colouring == "labels" else None
    frames = list(range(res.n_frames))
    painter = render.painter._Painter(res, frames, size=size, labels=labels, label_names=["key group"] if labels is not None
                              else None, show_contacts=False, title=title, max_speed=None)
    parts = painter.layout.boxes()
    expected = {"time"} | ({"title"} if title else set()) | \
        ({"colour bar", "colour bar label", "colour bar values"} if colouring != "labels" else set())
    assert set(parts) == expected
    if colouring != "labels":
        assert painter.quantity == colouring
    measured = {}
    for name in parts:
        union = None
        for f in frames:
            image = Image.new("RGB", size, render.BACKGROUND)
            painter._frame = f
            painter.header(ImageDraw.Draw(image), parts=[name])
            box = _ink_box(np.asarray(image))
            assert box is not None, name
            union = box if union is None else (min(union[0], box[0]), min(union[1], box[1]),
                                               max(union[2], box[2]), max(union[3], box[3]))
        assert 0 <= union[0] and 0 <= union[1] and union[2] <= size[0] and union[3] <= painter.layout.header, \
            (name, union, size)
        measured[name] = union
    names = sorted(measured)
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            assert not render.header._overlap(measured[a], measured[b]), (a, measured[a], b, measured[b], size)
    # the whole frame: its header holds only these parts, and the model lies below the header
    for f in (0, frames[-1]):
        frame = np.asarray(painter.draw(f))
        header = frame[:painter.layout.header].copy()
        for x0, y0, x1, y1 in measured.values():
            header[y0:y1, x0:x1] = render.BACKGROUND
        assert _ink_box(header) is None, (f, _ink_box(header))
        blocks = painter.view.pixels(res.vertices[f])
        assert blocks[:, 1].min() >= painter.layout.header
        assert blocks[:, 1].max() <= size[1] and blocks[:, 0].min() >= 0 and blocks[:, 0].max() <= size[0]
    if title == LONG_TITLE and size[0] == 320:
        assert painter.layout.title_text.endswith("…")  # shortened to the picture's width
    # text grows with large pictures
    assert render.text_size(size) == (10 if size[1] <= 480 else 15)


_NO_VIDEO = "the optional [video] extra (imageio-ffmpeg) is not installed: pip install 'ddatai[video]'"


def test_video_plays_at_the_stated_speed_and_shows_the_frames(tmp_path):
    """MP4 through imageio's ffmpeg plugin: a 3 s run at speed 1 and 25 frames/s is 76 video
    frames (a constant frame rate: each drawn frame repeated for its display time), of the
    asked size (an odd size padded to even), close to the drawn frames (H.264 is lossy)."""
    pytest.importorskip("imageio_ffmpeg", reason=_NO_VIDEO)
    import imageio.v2 as imageio

    res = _moving_square(np.linspace(0.0, 3.0, 61))
    path = dd.write_video(res, tmp_path / "a.mp4", size=(320, 240), fps=25.0, title="square")
    with imageio.get_reader(path, format="FFMPEG") as reader:
        back = [frame for frame in reader]
        assert reader.get_meta_data()["fps"] == pytest.approx(25.0)
    assert len(back) == 76 and back[0].shape == (240, 320, 3)
    drawn = dd.render_frames(res, size=(320, 240), frames=[0, 60], title="square")
    for a, b in ((back[0], drawn[0]), (back[-1], drawn[1])):
        assert np.abs(a.astype(int) - b.astype(int)).mean() < 6.0
    assert np.abs(back[0].astype(int) - back[-1].astype(int)).mean() > 1.0  # the square moved
    odd = dd.write_video(res, tmp_path / "odd.mp4", size=(161, 121), fps=10.0, speed=3.0)
    with imageio.get_reader(odd, format="FFMPEG") as reader:
        frames = [frame for frame in reader]
    assert frames[0].shape == (122, 162, 3) and len(frames) == 11


def test_video_is_streamed_and_smaller_than_the_gif_of_a_long_run(tmp_path, monkeypatch):
    """600 frames drawn one at a time: at most a few alive at once (the writer keeps none),
    and the MP4 is smaller than the GIF of the same frames."""
    pytest.importorskip("imageio_ffmpeg", reason=_NO_VIDEO)
    import weakref

    from ddatai import render

    res = _moving_square(np.linspace(0.0, 10.0, 600))
    refs: list = []
    most = [0]
    original = render.painter._Painter.image

    class Frame(np.ndarray):
        pass

    def image(self, frame):
        most[0] = max(most[0], sum(r() is not None for r in refs))
        out = original(self, frame).view(Frame)
        refs.append(weakref.ref(out))
        return out

    monkeypatch.setattr(render.painter._Painter, "image", image)
    mp4 = dd.write_video(res, tmp_path / "long.mp4", size=(320, 240), stride=1, fps=60.0)
    assert len(refs) == 600 and most[0] <= 3, most[0]
    gif = dd.write_gif(res, tmp_path / "long.gif", size=(320, 240), stride=1, fps=50.0)
    assert mp4.stat().st_size < gif.stat().st_size


def test_video_option_of_the_command_line(tmp_path, capsys):
    from ddatai.cli import main

    if importlib.util.find_spec("imageio_ffmpeg") is None:
        # without the extra: one line naming it, before any work
        assert main(["run", SLIDING, "--steps", "2", "--video", str(tmp_path / "v.mp4"),
                     "--out", str(tmp_path), "--quiet"]) == 2
        assert "pip install 'ddatai[video]'" in capsys.readouterr().err
        return
    assert main(["run", SLIDING, "--duration", "0.2", "--video", str(tmp_path / "v.mp4"),
                 "--size", "320x240", "--out", str(tmp_path), "--quiet"]) == 0
    assert (tmp_path / "v.mp4").stat().st_size > 0 and "video written to" in capsys.readouterr().out
    assert main(["run", SLIDING, "--steps", "2", "--video", str(tmp_path / "v.avi"),
                 "--out", str(tmp_path), "--quiet"]) == 2
    assert "must name a .mp4 file" in capsys.readouterr().err
