"""The documentation site and the README's first hour.

The slow test builds the site (Sphinx, the PyData theme, numpydoc, sphinx-gallery, MyST; the
``[docs]`` extra) as ``python -m sphinx -b html -W --keep-going -n docs OUT``: every warning and
every broken cross-reference fails it, and the gallery runs every scene script. It took 7.1
minutes on the shared 2-vCPU development machine (the scenes' simulations and GIFs are most of it); skipped without the
extra. The other tests are cheap checks of what the build and a new user rely on.
"""

from __future__ import annotations

import importlib.util
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCENES = sorted(p for p in (ROOT / "scenes").glob("*.py") if p.stem != "__init__")
DOCS_EXTRA = ("sphinx", "pydata_sphinx_theme", "numpydoc", "sphinx_gallery", "myst_parser", "matplotlib", "ezdxf")


def _readme() -> str:
    return (ROOT / "README.md").read_text(encoding="utf-8")


def test_readme_quick_start_ends_in_an_animation_shown_right_there():
    """The README's first command installs and runs a scene that writes its GIF; the picture
    above it is that scene's GIF, at least 640 × 480; the test command is there; the README is a
    README (under 200 lines)."""
    from PIL import Image

    text = _readme()
    assert len(text.splitlines()) < 200
    first = re.search(r"```bash\n(.*?)\n", text).group(1)
    install, _, run = first.partition("&&")
    assert "pip install" in install
    m = re.match(r"\s*python scenes/(\w+)\.py --gif (\S+\.gif)", run)
    assert m, run
    picture = re.search(r"!\[[^\]]*\]\((docs/gallery/(\w+)\.gif)\)", text)
    assert picture and picture.start() < text.index(first) and picture.group(2) == m.group(1)
    with Image.open(ROOT / picture.group(1)) as im:
        assert im.size[0] >= 640 and im.size[1] >= 480 and im.n_frames > 10
    assert "\npython -m pytest" in text  # CI runs the README's test command (.ci/run)


def test_gallery_pictures_are_at_least_640_by_480_and_of_sane_size():
    from PIL import Image

    gifs = sorted((ROOT / "docs" / "gallery").glob("*.gif"))
    assert len(gifs) >= 8
    for gif in gifs:
        with Image.open(gif) as im:
            assert im.size[0] >= 640 and im.size[1] >= 480, (gif.name, im.size)
        assert gif.stat().st_size < 1_500_000, gif.name


def test_scene_scripts_are_gallery_examples():
    """sphinx-gallery needs an RST title as the first lines of each script's docstring, and a
    scene must not end its script with SystemExit(0) (the gallery runs it in-process: only a
    failure exits, `ddatai.cli.run_as_script`)."""
    sys.path.insert(0, str(ROOT / "docs" / "_ext"))
    try:
        from gallery_helpers import ORDER
    finally:
        sys.path.remove(str(ROOT / "docs" / "_ext"))
    for path in SCENES:
        text = path.read_text(encoding="utf-8")
        m = re.match(r'"""\n(.+)\n(=+)\n\n', text)
        assert m and len(m.group(2)) == len(m.group(1)), f"{path.name}: no RST title in its docstring"
        assert "run_as_script(" in text and "SystemExit(scene_main" not in text, path.name
        assert path.stem in ORDER, f"{path.name} has no place in docs/_ext/gallery_helpers.py ORDER"


@pytest.mark.slow
def test_the_documentation_site_builds_without_warnings(tmp_path):
    """About 7 minutes on 2 cores (428 s measured). Every scene has a gallery page with its animation (a GIF of at
    least 640 × 480) right above its code, the API reference has pages for the public names, and
    the guide pages that the README links are there."""
    missing = [m for m in DOCS_EXTRA if importlib.util.find_spec(m) is None]
    if missing:
        pytest.skip(f"the optional [docs] extra is not installed ({', '.join(missing)} missing): "
                    "pip install -e '.[docs]'")
    from PIL import Image

    out = tmp_path / "html"
    env = dict(os.environ, PYTHONPATH=str(ROOT), DDATAI_GALLERY_RUNS=str(tmp_path / "runs"))
    (tmp_path / "runs").mkdir()
    # run_stale_examples: every scene runs, whatever an earlier build left in docs/gallery_scenes
    proc = subprocess.run([sys.executable, "-m", "sphinx", "-b", "html", "-W", "--keep-going", "-n", "-q",
                           "-D", "sphinx_gallery_conf.run_stale_examples=True",
                           str(ROOT / "docs"), str(out)], capture_output=True, text=True, cwd=ROOT, env=env,
                          timeout=1800)
    assert proc.returncode == 0, (proc.stdout[-4000:], proc.stderr[-8000:])
    assert "WARNING" not in proc.stderr and "ERROR" not in proc.stderr, proc.stderr[-8000:]
    for path in SCENES:
        page = (out / "gallery_scenes" / f"{path.stem}.html").read_text(encoding="utf-8")
        gifs = re.findall(r'src="(\.\./_images/[^"]+\.gif)"', page)
        assert len(gifs) == 1, (path.stem, gifs)
        with Image.open(out / "gallery_scenes" / gifs[0]) as im:
            assert im.size[0] >= 640 and im.size[1] >= 480, (path.stem, im.size)
        # the animation, then the scene's code right below it (sphinx-gallery shows the output of
        # a one-block script above its code)
        assert page.index(gifs[0]) < page.index('class="nf">build<'), path.stem
    for name in ("ddatai.Results", "ddatai.simulate", "ddatai.write_video", "kgm.probabilistic", "kgm.analyze"):
        assert (out / "api" / "generated" / f"{name}.html").is_file(), name
    for page in ("getting_started", "guide/scenes", "guide/equilibrium_start", "kgm/studies", "method/dda"):
        assert (out / f"{page}.html").is_file(), page
