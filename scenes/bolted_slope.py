"""
Bolted slope under a water table
================================

A jointed slope with a water table, bolted until kgm's factor of safety reaches 1.5.

A 20 m high, 60° face (looking to +x) over a bedding plane dipping 35° that daylights in the
face 2 m above the toe (φ = 32°, c = 20 kPa), with a vertical tension crack 6 m deep behind the crest and two
steep cross joints cutting the wedge into three blocks. Winter water table: the crack holds
5 m of water and the pressure on the plane falls linearly to zero where it daylights (Hoek & Bray's
distribution, docs/method/water_bolts.md). Unbolted, kgm (Sarma) gives FS ≈ 0.87 and DDA shows
the wedge sliding out. ``build("design")`` adds rows of passive bolts (32 mm bars of 300 kN at 1.5 m
across the slope: 10.7 MN/m per m stiffness, 200 kN/m capacity, plunging 15° into the slope)
up the face until kgm's least safe key group has FS ≥ 1.5; DDA then shows the wedge held.
With one row of half the capacity (``build(bolts="weak")``, FS ≈ 0.94) the bolt breaks and the
wedge slides.

Run ``python scenes/bolted_slope.py --gif out/bolted_slope.gif`` (the design) or
``kgm analyze scenes/bolted_slope.py``. The pictures of docs/guide/water_bolts.md::

    for case in ("weak", "design"):
        res = dd.simulate(*build(case), duration=2.0, record_every=2)
        dd.write_gif(res, f"docs/gallery/bolted_slope{'_weak' if case == 'weak' else ''}.gif",
                     title=f"bolted_slope: {case}")
"""

import math

import ddatai as dd

DURATION = 2.0  # s
HEIGHT, FACE, PLANE, CRACK, WATER = 20.0, 60.0, 35.0, 6.0, 5.0   # m, °, °, m, m
DAYLIGHT = 2.0  # height above the toe where the plane daylights in the face [m]
FS_TARGET = 1.5
#: one row of bolts per metre of slope: 32 mm bars (E = 200 GPa, 10 m free length, 300 kN)
#: at 1.5 m across the slope
BOLT_STIFFNESS = 200e9 * math.pi * 0.016 ** 2 / 10.0 / 1.5       # N/m per m
BOLT_CAPACITY = 300e3 / 1.5                                       # N/m
BOLT_PLUNGE = 15.0                                                # degrees below horizontal


def slope(bolt_rows: int = 0, capacity: float = BOLT_CAPACITY) -> dd.Scene:
    """The slope with its water table and the first ``bolt_rows`` rows of bolts (from the toe
    up the face), each of ``capacity`` [N/m]."""
    rock = dd.Material(density=2600.0, young=10e9, poisson=0.25)
    scene = dd.Scene(gravity=9.81)
    tp = math.tan(math.radians(PLANE))
    cot_face = 1.0 / math.tan(math.radians(FACE))
    xd, yd = -DAYLIGHT * cot_face, DAYLIGHT                      # where the plane daylights in the face
    xc = xd - (HEIGHT - CRACK - yd) / tp                          # the crack's abscissa
    crest = -HEIGHT * cot_face
    boundary = [(-50.0, -15.0), (25.0, -15.0), (25.0, 0.0), (0.0, 0.0), (crest, HEIGHT), (-50.0, HEIGHT)]
    bedding = dd.Joint(friction=32.0, cohesion=20e3)
    cross = dd.Joint(friction=35.0, cohesion=10e3)
    plane = [(xd + 2.0, yd - 2.0 * tp), (xc - 3.0, yd + (xd - xc + 3.0) * tp)]   # from the air in front of the face
    traces = [(plane, bedding), ([(xc, HEIGHT + 1.0), (xc, HEIGHT - CRACK - 1.0)], bedding)]
    down = (-math.cos(math.radians(80.0)), -math.sin(math.radians(80.0)))
    for x in (xc + 6.0, xc + 12.0):                                # cross joints dipping 80° into the slope
        traces.append(([(x, HEIGHT + 1.0), (x + 30.0 * down[0], HEIGHT + 1.0 + 30.0 * down[1])], cross))
    for b in scene.cut(boundary, traces, material=rock):
        cx, cy = scene.polygon(b).mean(axis=0)
        scene.set_fixed(b, not (xc < cx < xd and cy > yd + (xd - cx) * tp))
    scene.set_joint(bedding)
    scene.set_water_table([(-50.0, HEIGHT - CRACK + WATER), (xc, HEIGHT - CRACK + WATER), (xd, yd),
                           (25.0, yd)])
    plunge = math.radians(BOLT_PLUNGE)
    for k in range(bolt_rows):
        y = yd + 1.5 + 2.5 * k                                    # rows every 2.5 m up the face
        x = -y * cot_face - 0.3                                   # 0.3 m behind the face
        above = y - (yd + (xd - x) * tp)                          # height above the plane
        length = 8.0 + above * math.cos(math.radians(PLANE)) / math.sin(math.radians(PLANE) + plunge)
        scene.add_bolt((x, y), (x - length * math.cos(plunge), y - length * math.sin(plunge)),
                       stiffness=BOLT_STIFFNESS, capacity=capacity)
    return scene


def design(fs_target: float = FS_TARGET, method: str = "sarma") -> tuple[int, list[float]]:
    """Rows of bolts needed for kgm's least safe key group to reach ``fs_target``, and the FS
    after each row added (row 0: unbolted)."""
    import kgm

    history = []
    for rows in range(0, 8):
        fs = kgm.analyze(slope(rows), method=method).critical.fs
        history.append(fs)
        if fs >= fs_target:
            return rows, history
    raise RuntimeError(f"8 rows of bolts do not reach FS {fs_target}: {history}")


def build(bolts: str = "design"):
    """Returns (scene, params). ``bolts``: "none", "weak" (one row of half the capacity) or
    "design" (the rows that give FS ≥ 1.5)."""
    if bolts not in ("none", "weak", "design"):
        raise ValueError(f"bolts must be 'none', 'weak' or 'design', got {bolts!r}")
    if bolts == "weak":
        return slope(1, capacity=0.5 * BOLT_CAPACITY), dd.Params()
    return slope(design()[0] if bolts == "design" else 0), dd.Params()


if __name__ == "__main__":
    from ddatai.cli import run_as_script

    run_as_script(build, DURATION, "bolted_slope")
