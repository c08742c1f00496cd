"""The gallery's hooks (named in ``conf.py`` by their import path, so that the configuration
stays picklable): every scene script runs as ``python scenes/NAME.py --gif NAME.gif`` would,
and the GIF it writes is placed beside its code."""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

#: where the scene scripts write their GIF and results during a build
RUNS = Path(os.environ.get("DDATAI_GALLERY_RUNS") or tempfile.mkdtemp(prefix="ddatai-gallery-"))
#: options beyond the GIF's, per scene (toppling_slope runs its DDA simulation with --dda)
EXTRA_ARGS = {"toppling_slope": ["--dda", "--every", "15"]}
#: the gallery's order: the quick start's scene first, then by what they show
ORDER = ["sliding_block", "toppling", "rockfall", "masonry_wall", "jointed_slope", "stacked_grid",
         "bolted_slope", "dxf_section", "example_1", "example_2", "kgm_slope", "toppling_slope", "footwall"]


def scene_argv(gallery_conf, script_vars) -> list[str]:
    """The command line a scene script gets (``sys.argv[1:]``)."""
    stem = Path(script_vars["src_file"]).stem
    return [*EXTRA_ARGS.get(stem, []), "--gif", str(RUNS / f"{stem}.gif"), "--out", str(RUNS), "--quiet"]


class SceneOrder:
    """Sort key of the scene scripts (`ORDER`, then by name)."""

    def __init__(self, src_dir):
        self.src_dir = src_dir

    def __call__(self, filename: str):
        stem = Path(filename).stem
        return (ORDER.index(stem) if stem in ORDER else len(ORDER), stem)

    def __repr__(self) -> str:
        return "SceneOrder"


def gif_scraper(block, block_vars, gallery_conf, **kwargs) -> str:
    """The GIF the scene script wrote, moved beside its code on the page."""
    from sphinx_gallery.scrapers import figure_rst

    stem = Path(block_vars["src_file"]).stem
    written = RUNS / f"{stem}.gif"
    if not written.exists():
        return ""
    image_path = Path(next(block_vars["image_path_iterator"]))
    target = image_path.with_suffix(".gif")
    shutil.move(str(written), target)
    # the gallery's thumbnail: the animation's last frame, where sphinx-gallery looks for it
    from PIL import Image

    with Image.open(target) as gif:
        gif.seek(gif.n_frames - 1)
        gif.convert("RGB").save(image_path.with_suffix(".png"))
    return figure_rst([str(target)], gallery_conf["src_dir"])
