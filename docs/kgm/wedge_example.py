"""The example wedge of docs/kgm/wedge.md from Python: its factor of safety, support, a
probabilistic study and the pictures of that page.

    python docs/kgm/wedge_example.py [--n 100000] [--out docs/kgm]

The same wedge as ``kgm wedge docs/kgm/wedge_example.toml``: Hoek & Bray's comprehensive example
geometry at 30 m, cohesive joints, a tension crack 12 m behind the crest, the fissures half
filled with water and a seismic coefficient of 0.08.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import scipy.stats as st

import ddatai as dd
import kgm


def build(**kw) -> "kgm.Wedge":
    """The example wedge (keyword arguments override `kgm.wedge`'s)."""
    j1 = dd.Joint(friction=20.0, cohesion=24e3)
    j2 = dd.Joint(friction=30.0, cohesion=48e3)
    args = dict(tension_crack=kgm.TensionCrack(kgm.Plane(70, 165), 12.0), water=kgm.Water(fill=0.5),
                seismic=0.08, density=2600.0)
    args.update(kw)
    return kgm.wedge(kgm.Plane(65, 185), kgm.Plane(12, 195), 30.0, [kgm.Plane(45, 105, j1), kgm.Plane(70, 235, j2)],
                     **args)


VARIABLES = {"joint1_orientation": kgm.Fisher(60.0), "joint2_orientation": kgm.Fisher(60.0),
             "joint1_friction": st.norm(20.0, 2.0), "joint2_friction": st.norm(30.0, 3.0),
             "water_fill": st.uniform(0.0, 1.0)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=100_000)
    ap.add_argument("--out", default=str(Path(__file__).resolve().parent))
    ap.add_argument("--frames", type=int, default=24)
    args = ap.parse_args()
    w = build()
    print(w.summary())
    s = w.required_support(1.5)
    print(f"for FS 1.5: an anchor of {s.force / 1e3:.0f} kN plunging {s.plunge:.1f}° towards {s.trend:.1f}°, "
          f"or {s.pressure / 1e3:.1f} kPa on the face")
    study = kgm.wedge_study(w, VARIABLES, args.n, sampling="latin-hypercube", seed=1,
                            correlation={("joint1_friction", "joint2_friction"): 0.5}, min_volume=50.0)
    print(study.summary())
    out = Path(args.out)
    w.write_gif(out / "wedge.gif", frames=args.frames)
    w.stereonet(out / "wedge_stereonet.png")
    print(f"wrote {out / 'wedge.gif'} and {out / 'wedge_stereonet.png'}")


if __name__ == "__main__":
    main()
