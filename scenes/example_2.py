"""
KGM Example II: active and passive blocks
=========================================

Example II of the seed paper (§5-2): a 95 m high rock slope with a two-block key group.

The paper gives c = 0.02 MPa, φ = 22°, ν = 0.25, ρ = 2500 kg/m³, "normal stiffness 1",
Δt = 0.0013 s (Table 2) and reports that the original KGM finds the candidate key group
stable while the Sarma-based KGM and DDA find it unstable; its figure and coordinates are not
available. Choices where the paper is open:

* **Geometry**: an active–passive (bi-planar) wedge, after the reconstruction of
  docs/kgm/method.md §8.3 with one change. Slope face 50°, crest C = (0, 95), toe T = (79.714, 0),
  horizontal ground behind the crest and in front of the toe. J1 (base, dips 15° out of the
  slope) runs from T to Q = (21.759, 15.529); J2 (rear, dips 70°) from Q up to
  C' = (−7.166, 95) on the upper ground. The cross joint J3 rises at 70° from the point Q'
  2 m up J2 from Q to the face at F. Passive block P = T F Q' Q (on J1 and on J2 below Q'),
  active block A = Q' F C C' (on J2 above Q'), the rest fixed.
  *Why not §8.3 as is* (J3 from Q itself, rising at 45°; ``build(cross_joint_offset=0,
  cross_joint_angle=45)``, kept for the limit-equilibrium targets of §8.4): there the Sarma
  mechanism (A down J2, P out along J1) needs A's lowest corner, at Q, to move down the line of
  J2 into the rock under J1 — Sarma's slices see only the joints, not that corner. DDA on that
  real geometry cannot move A that way: the group only translates along J1 as one body, and
  it stays stable at 22° (DDA φc ≈ 13–17°, the rigid value). Starting J3 2 m up J2 gives A's
  corner room to follow J2 while P moves out, so the multi-block mechanism exists in the real
  geometry too.
  Results (limit equilibrium, φ = 22°, c = 20 kPa): P alone FS 1.66, A alone no mode;
  rigid {A, P} can only slide on the gentle J1: FS 1.59 ("stable"); Sarma {A, P}: FS 0.77
  ("unstable"): the behaviour the paper reports.
* **Young's modulus**: not given; E = 5 GPa as in Example I.
* **"Normal stiffness 1"**: read as the penalty ratio p = 1·E (= 5e9 N/m per m), following the
  reading of Example I's "10"; the contact settlement under the 95 m slope (≈ σ/p ≈ 0.5 mm)
  stays far below the displacement criterion of the DDA judgement.
* **Time step**: Δt = 0.0013 s, fixed, as in the paper.

Block ids: P (passive, toe) = 0, A (active, upper) = 1, fixed rock = 2.
Run ``python scenes/example_2.py`` (plain DDA run) or ``kgm analyze scenes/example_2.py``.
"""

import numpy as np

import ddatai as dd

DURATION = 3.0  # s
P, A, ROCK = 0, 1, 2
C, T, Q, C2 = np.array((0.0, 95.0)), np.array((79.714, 0.0)), np.array((21.759, 15.529)), np.array((-7.166, 95.0))


def cross_joint(offset: float, angle: float) -> tuple[np.ndarray, np.ndarray]:
    """Ends of J3: its foot Q' = Q + offset·(unit vector up J2) [m], and F where the line
    rising at ``angle`` [degrees] from Q' meets the slope face T–C."""
    up = (C2 - Q) / np.linalg.norm(C2 - Q)
    foot = Q + offset * up
    d = np.array([np.cos(np.radians(angle)), np.sin(np.radians(angle))])
    s, _ = np.linalg.solve(np.column_stack([d, T - C]), T - foot)
    return foot, foot + s * d


def build(friction: float = 22.0, cohesion: float = 0.02e6, young: float = 5e9,
          cross_joint_offset: float = 2.0, cross_joint_angle: float = 70.0):
    """Returns (scene, params). ``friction`` [degrees] and ``cohesion`` [Pa] of all joints;
    ``cross_joint_offset`` [m] and ``cross_joint_angle`` [degrees] place J3 (0 and 45: the
    reconstruction of docs/kgm/method.md §8.3)."""
    scene = dd.Scene(gravity=9.81)
    rock = dd.Material(density=2500.0, young=young, poisson=0.25)
    foot, f = cross_joint(cross_joint_offset, cross_joint_angle)
    scene.add_block([T, f, foot, Q] if cross_joint_offset > 0 else [T, f, Q], material=rock)  # P
    scene.add_block([foot, f, C, C2], material=rock)                                         # A
    scene.add_block([(-60, -30), (130, -30), (130, 0), T, Q, C2, (-60, 95)], material=rock,
                    fixed=True)                                                           # rock
    scene.set_joint(dd.Joint(friction=friction, cohesion=cohesion, tensile=0.0))
    return scene, dd.Params(dt=0.0013, penalty_ratio=1.0)


if __name__ == "__main__":
    from ddatai.cli import run_as_script

    run_as_script(build, DURATION, "example_2")
