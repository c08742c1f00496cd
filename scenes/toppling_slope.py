"""
Block toppling (Goodman and Bray)
=================================

Block toppling: Goodman & Bray's (1976) example of 16 blocks on a stepped base (Hoek & Bray
1981, Rock Slope Engineering, ch. 10; Wyllie & Mah 2004, §10.3).

Sixteen blocks, each Δx = 10 m wide, stand on a stepped base whose treads dip ψp = 30°; their
sides are perpendicular to the base (dipping 60°). Along the base the slope face rises
a1 = 5 m per block, the upper slope falls a2 = 5 m per block above the crest (block 10), and
the base steps up b = 1 m per block, so the block heights (perpendicular to the base) are
y_n = n(a1 − b) for n ≤ 10 and y_n = y_{n−1} − a2 − b above the crest:
4, 8, …, 40, 34, 28, 22, 16, 10, 4 m (slope face 56.6°, upper slope 3.4°). The same friction
angle holds on the bases and between blocks; no cohesion. The published answer: limit
equilibrium needs φ = 38.15°, with blocks 16–14 stable, 13–4 toppling and 3–1 sliding.

The stable rock below the stepped base is one fixed block. Block ids: block n of the textbook
(toe n = 1) is scene block n − 1; the fixed base is block 16. ``python scenes/toppling_slope.py``
prints the Goodman–Bray table computed by ``kgm`` against the published modes;
``python scenes/toppling_slope.py --dda`` then also runs the plain DDA simulation.
"""

import numpy as np

import ddatai as dd

DURATION = 3.0  # s
N_BLOCKS = 16
WIDTH = 10.0       # Δx [m]
BASE_DIP = 30.0    # ψp [degrees]
A1, A2, STEP = 5.0, 5.0, 1.0   # a1, a2, b [m]
CREST = 10         # the crest block (textbook numbering)
UNIT_WEIGHT = 25e3  # γ [N/m³] of the textbook example
#: Published modes, textbook block n -> mode (Hoek & Bray 1981; Wyllie & Mah 2004).
PUBLISHED_MODES = {n: ("stable" if n >= 14 else "toppling" if n >= 4 else "sliding")
                   for n in range(1, N_BLOCKS + 1)}
PUBLISHED_CRITICAL_FRICTION = 38.15  # degrees
BASE_BLOCK = N_BLOCKS  # scene id of the fixed base


def block_heights() -> list[float]:
    """y_n [m], n = 1..16: n(a1 − b) up to the crest, then y_{n−1} − a2 − b."""
    heights: list[float] = []
    for n in range(1, N_BLOCKS + 1):
        heights.append(n * (A1 - STEP) if n <= CREST else heights[-1] - A2 - STEP)
    return heights


def build(friction: float = 35.0, cohesion: float = 0.0, young: float = 10e9):
    """Returns (scene, params). ``friction`` [degrees] and ``cohesion`` [Pa] of every joint."""
    psi = np.radians(BASE_DIP)
    upslope = np.array([-np.cos(psi), np.sin(psi)])   # along the base, up the slope (faces +x)
    normal = np.array([np.sin(psi), np.cos(psi)])     # perpendicular to the base, upward

    def at(along: float, across: float) -> np.ndarray:
        return along * upslope + across * normal

    rock = dd.Material(density=UNIT_WEIGHT / 9.81, young=young, poisson=0.25)
    scene = dd.Scene(gravity=9.81)
    for n, y in enumerate(block_heights(), start=1):
        x0, b0 = (n - 1) * WIDTH, (n - 1) * STEP  # downslope side, base level of block n
        scene.add_block([at(x0, b0), at(x0 + WIDTH, b0), at(x0 + WIDTH, b0 + y), at(x0, b0 + y)],
                        material=rock)
    # the stable rock: treads and risers of the stepped base, ground in front of the toe
    steps = [at(0.0, 0.0)]
    for n in range(1, N_BLOCKS + 1):
        steps.append(at(n * WIDTH, (n - 1) * STEP))
        if n < N_BLOCKS:
            steps.append(at(n * WIDTH, n * STEP))
    back = at(N_BLOCKS * WIDTH + WIDTH, (N_BLOCKS - 1) * STEP)
    # in front of the toe the rock follows the toe block's base plane down (the base daylights,
    # as the recursion assumes): a ground surface at the toe's level would buttress block 1
    # and stop it sliding
    daylight = at(-20.0, 0.0)
    bottom = daylight[1] - 20.0
    scene.add_block([(daylight[0], bottom), daylight, *steps, back, (back[0], bottom)], material=rock, fixed=True)
    scene.set_joint(dd.Joint(friction=friction, cohesion=cohesion, tensile=0.0))
    return scene, dd.Params(dt=0.002, penalty_ratio=10.0)


def toppling_table(friction: float = PUBLISHED_CRITICAL_FRICTION) -> tuple[list, float]:
    """The Goodman–Bray recursion of the whole row at the friction angle ``friction`` and the
    row's critical friction angle: (steps top block first, φc [degrees])."""
    from kgm.build import build_block_system
    from kgm.candidates import toppling_row
    from kgm.judges.toppling import recursion, row_critical_friction

    scene, _ = build(friction=friction)
    row = toppling_row(build_block_system(scene), frozenset(range(N_BLOCKS)))
    return list(recursion(row)), row_critical_friction(row)


def main() -> None:
    import kgm

    steps, phi_c = toppling_table()
    print(f"Goodman & Bray's block-toppling example at phi = {PUBLISHED_CRITICAL_FRICTION} deg "
          f"(forces per m, gamma = {UNIT_WEIGHT / 1e3:.0f} kN/m3)")
    print(f"{'n':>3} {'y_n':>6} {'M_n':>6} {'L_n':>6} {'P_n':>9} {'P_n-1,t':>9} {'P_n-1,s':>9}  "
          f"{'mode':<9} published")
    for s in steps:
        n = s.block + 1
        print(f"{n:>3} {s.height:6.1f} {s.contact_above:6.1f} {s.contact_below:6.1f} {s.force_above / 1e3:9.1f} "
              f"{s.force_toppling / 1e3:9.1f} {s.force_sliding / 1e3:9.1f}  {s.state.value:<9} "
              f"{PUBLISHED_MODES[n]}")
    print(f"critical friction angle: {phi_c:.2f} deg (published {PUBLISHED_CRITICAL_FRICTION} deg)")
    scene, _ = build()
    for method in ("rigid", "sarma"):
        rep = kgm.analyze(scene, method=method)
        crit = rep.critical
        print(f"kgm.analyze({method!r}) at phi = 35 deg: critical group "
              f"{{{', '.join(str(b + 1) for b in sorted(crit.blocks))}}} (textbook numbers), "
              f"mode {crit.mode.kind.value}, FS = {crit.fs:.3f}, phi_c = {crit.critical_friction:.2f} deg")


if __name__ == "__main__":
    import sys

    main()
    if "--dda" in sys.argv:
        from ddatai.cli import run_as_script

        sys.argv.remove("--dda")
        run_as_script(build, DURATION, "toppling_slope")
