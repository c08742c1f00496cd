"""
KGM Example I: a two-block key group
====================================

Example I of Shahami, Yarahmadi Bafghi & Fatehi Marji (the seed paper, §5-1): a simple key
group of two blocks.

Four blocks, the bottom one fixed. The paper gives the material and joint data (Table 1:
c = 0.02 MPa, φ = 11°, ν = 0.25, ρ = 2500 kg/m³, "normal stiffness 10", Δt = 0.0013 s,
g = 9.81 m/s²) and reports a critical friction angle of 11° for the two-block key group; its
figure and coordinates are not available. Choices where the paper is open:

* **Geometry**: the reconstruction of docs/kgm/method.md §8.2 (all coordinates in m). A sliding
  joint dipping 20° daylights at the toe (0, 0) above a 5 m vertical toe cut; vertical cross
  joints at x = −4 and x = −10; a horizontal bench at y = 10·tan 20°. B1 (toe) and B2 rest on
  the 20° joint, B3 on the bench, B4 is the fixed base. With c = 20 kPa the group {B1, B2}
  reaches limit equilibrium at φ = 11.02° (rigid and Sarma), which is how the reconstruction
  was chosen; B1 alone at 8.41°.
* **Young's modulus**: not given; E = 5 GPa (a typical intact-rock value; the rigid-body
  answers do not depend on it, DDA's only through the small elastic settlement).
* **"Normal stiffness 10"**: read as the DDA penalty ratio p = 10·E (= 5e10 N/m per m),
  within the usual 10–100·E range (docs/method/dda.md §6.3); the alternative "10 GN/m" (p = 2·E)
  would only soften the contacts.
* **Time step**: Δt = 0.0013 s, fixed, as in the paper; dynamic run (velocity carried over).

Block ids: B1 = 0, B2 = 1, B3 = 2, B4 (fixed base) = 3. All joints share the default joint
(c = 20 kPa, φ = 11°, no tensile strength).

Run ``python scenes/example_1.py`` (plain DDA run) or ``kgm analyze scenes/example_1.py``.
"""

import numpy as np

import ddatai as dd

DURATION = 2.0  # s
B1, B2, B3, B4 = 0, 1, 2, 3
DIP = 20.0  # degrees, the sliding joint


def build(friction: float = 11.0, cohesion: float = 0.02e6, young: float = 5e9):
    """Returns (scene, params). ``friction`` [degrees] and ``cohesion`` [Pa] of all joints."""
    scene = dd.Scene(gravity=9.81)
    rock = dd.Material(density=2500.0, young=young, poisson=0.25)
    tan = np.tan(np.radians(DIP))
    y4, y10 = 4.0 * tan, 10.0 * tan  # the sliding joint under the cross joints
    scene.add_block([(0, 0), (0, 5), (-4, 5), (-4, y4)], material=rock)                  # B1
    scene.add_block([(-4, y4), (-4, 8.8), (-10, 8.8), (-10, y10)], material=rock)        # B2
    scene.add_block([(-10, y10), (-10, 8.8), (-16, 8.8), (-16, y10)], material=rock)     # B3
    scene.add_block([(-20, -10), (10, -10), (10, -5), (0, -5), (0, 0), (-10, y10), (-20, y10)],
                    material=rock, fixed=True)                                            # B4
    scene.set_joint(dd.Joint(friction=friction, cohesion=cohesion, tensile=0.0))
    return scene, dd.Params(dt=0.0013, penalty_ratio=10.0)


if __name__ == "__main__":
    from ddatai.cli import run_as_script

    run_as_script(build, DURATION, "example_1")
