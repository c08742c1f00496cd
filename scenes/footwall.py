"""
KGM footwall slopes: a slab on its bedding plane
================================================

Footwall slopes: a face slab on its bedding plane, the three limit-equilibrium mechanisms
after Alejano et al. (planar slab sliding, ploughing, bilinear slab failure), each with a small
geometry and its closed-form factor of safety (docs/kgm/footwall.md).

The slope faces +x. The bedding plane dips ψ out of the slope and the face is parallel to it,
a slab of thickness t above it (a footwall: the slope was excavated along the bedding). All
joints share one strength (φ, c), no tensile strength; ρ = 2500 kg/m³.

* ``"planar"`` (§2 of the doc): the slab, length L along the dip, undercut at its toe (the rock
  below its lower end drops away vertically), slides down the bedding as one body.
  Block ids: slab 0, rock 1.
* ``"ploughing"`` (§3): the slab reaches the pit floor. A release joint J1 rising at δ into
  the slope from the bedding to the face, and a vertical cross joint J2 above it, cut a toe
  block P out of the slab; the slab above, A, slides down the bedding and pushes P up J1 (P
  "ploughs" out of the face). The slab below J1 stands on the floor and is part of the rock.
  Block ids: P = 0, A = 1, rock = 2.
* ``"bilinear"`` (§4): the same slab cut by a release joint J1 dipping β < ψ out of the slope
  (daylighting in the face) and a cross joint J2 perpendicular to the bedding; A slides down
  the bedding and drives P out along J1, shearing J2 (an active–passive, bi-planar failure).
  Block ids: P = 0, A = 1, rock = 2.

``closed_form_fs`` gives each case's limit-equilibrium answer computed by hand from the
geometry (the referee of tests/test_kgm_footwall.py and benchmarks/kgm_examples.py);
``rigid_fs`` the answer of the group glued into one body; ``turning_fs`` that of the bilinear
pair turning as one body on two sliding points (docs/kgm/footwall.md §9).

Run ``python scenes/footwall.py`` (plain DDA run of the bilinear case) or
``kgm analyze scenes/footwall.py``.
"""

from __future__ import annotations

import math

import numpy as np

import ddatai as dd

DURATION = 2.0  # s
CASES = ("planar", "ploughing", "bilinear")
DENSITY = 2500.0  # kg/m³
G = 9.81          # m/s²
P, A, ROCK = 0, 1, 2          # ploughing and bilinear
SLAB, SLAB_ROCK = 0, 1        # planar

#: Default geometry and strength of each case: dip ψ [degrees], slab thickness t [m], slope
#: height H or slab length L [m], the release joint J1 (dip [degrees], positive out of the
#: slope, negative rising into it; its foot along the bedding from the floor [m]), the cross
#: joint J2 (dip [degrees] as J1, None: perpendicular to the bedding; its foot [m]), φ
#: [degrees], c [Pa].
DEFAULTS = {
    "planar": dict(dip=40.0, thickness=1.5, length=12.0, friction=30.0, cohesion=10e3),
    "ploughing": dict(dip=60.0, thickness=2.0, height=30.0, toe_dip=-35.0, toe_foot=1.0, cross_dip=90.0,
                      cross_foot=3.0, friction=25.0, cohesion=0.0),
    "bilinear": dict(dip=50.0, thickness=2.0, height=24.0, toe_dip=25.0, toe_foot=3.0, cross_dip=None,
                     cross_foot=6.0, friction=30.0, cohesion=5e3),
}


def _unit(deg: float) -> np.ndarray:
    """Unit vector of a line dipping ``deg`` toward +x (negative: rising toward +x)."""
    return np.array([math.cos(math.radians(deg)), -math.sin(math.radians(deg))])


def geometry(case: str = "bilinear", **options) -> dict:
    """The vertices of a case [m] (``options`` override `DEFAULTS`): ``"slab"``, ``"rock"``
    for the planar case; ``"P"``, ``"A"``, ``"rock"`` and the named points B, C, F, G, K, K2
    (J1 from B on the bedding to F on the face, J2 from C to G, the slab's crest K–K2) for the
    two-block cases; and the parameters used."""
    if case not in CASES:
        raise ValueError(f"footwall case must be one of {CASES}, got {case!r}")
    unknown = set(options) - set(DEFAULTS[case])
    if unknown:
        raise ValueError(f"footwall case {case!r} has no option(s) {sorted(unknown)}; it takes {sorted(DEFAULTS[case])}")
    p = {**DEFAULTS[case], **options}
    psi = math.radians(p["dip"])
    up = np.array([-math.cos(psi), math.sin(psi)])       # up the bedding
    out = np.array([math.sin(psi), math.cos(psi)])       # bedding normal, out of the slope
    t = p["thickness"]
    if case == "planar":
        lo = np.zeros(2)
        hi = lo + p["length"] * up
        slab = [lo, lo + t * out, hi + t * out, hi]
        # the rock: the bedding from the slab's toe up to the crest, a vertical drop below the toe
        rock = [(-p["length"] - 10.0, -8.0), (0.0, -8.0), lo, hi, (hi[0] - 10.0, hi[1])]
        return dict(slab=np.array(slab), rock=np.array(rock, dtype=float), params=p)
    h = p["height"]

    def on_face(start: np.ndarray, dip: float) -> np.ndarray:
        # start + a·d on the face line {s·up + t·out}
        a, _ = np.linalg.solve(np.column_stack([_unit(dip), -up]), t * out - start)
        return start + a * _unit(dip)

    b = p["toe_foot"] * up
    c = p["cross_foot"] * up
    f = on_face(b, p["toe_dip"])
    g = c + t * out if p["cross_dip"] is None else on_face(c, p["cross_dip"])
    toe = np.array([t / math.sin(psi), 0.0])             # the face at the floor
    k = h / math.sin(psi) * up                           # the bedding at the crest
    k2 = k + toe                                         # the face at the crest
    if not (toe[1] < f[1] and f @ up < g @ up and b @ up < c @ up and g[1] < h):
        raise ValueError(f"footwall {case}: J1 must meet the face above the floor and below J2, and J2 "
                         f"below the crest (got F = {f.round(3)}, G = {g.round(3)})")
    rock = [(-h / math.tan(psi) - 12.0, -6.0), (toe[0] + 12.0, -6.0), (toe[0] + 12.0, 0.0), toe, f, b, k,
            (-h / math.tan(psi) - 12.0, h)]
    return dict(P=np.array([b, f, g, c]), A=np.array([c, g, k2, k]), rock=np.array(rock, dtype=float),
                B=b, C=c, F=f, G=g, K=k, K2=k2, params=p)


def build(case: str = "bilinear", young: float = 5e9, **options):
    """Returns (scene, params) of a case (``options`` override `DEFAULTS`; ``young`` [Pa])."""
    geo = geometry(case, **options)
    p = geo["params"]
    rock = dd.Material(density=DENSITY, young=young, poisson=0.25)
    scene = dd.Scene(gravity=G)
    if case == "planar":
        scene.add_block(geo["slab"], material=rock)
        scene.add_block(geo["rock"], material=rock, fixed=True)
    else:
        scene.add_block(geo["P"], material=rock)
        scene.add_block(geo["A"], material=rock)
        scene.add_block(geo["rock"], material=rock, fixed=True)
    scene.set_joint(dd.Joint(friction=p["friction"], cohesion=p["cohesion"], tensile=0.0))
    return scene, dd.Params(dt=0.002, penalty_ratio=10.0)


# ---------------------------------------------------------------------- closed forms
def _area(xy: np.ndarray) -> float:
    x, y = xy[:, 0], xy[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def _cross(a: np.ndarray, b: np.ndarray) -> float:
    return float(a[0] * b[1] - a[1] * b[0])


def planar_fs(*, dip: float, length: float, thickness: float, friction: float, cohesion: float,
              unit_weight: float = DENSITY * G) -> float:
    """A slab of length L and thickness t on a plane dipping ψ (docs/kgm/footwall.md eq. F1):
    FS = (c·L + W cosψ tanφ) / (W sinψ), W = γ·L·t."""
    psi = math.radians(dip)
    w = unit_weight * length * thickness
    return (cohesion * length + w * math.cos(psi) * math.tan(math.radians(friction))) / (w * math.sin(psi))


def two_block_residual(reduction: float, blocks: dict) -> tuple[float, dict]:
    """Equilibrium of the active block A (on the bedding) and the passive block P (on J1)
    with the shared joint J2, all at the strength (c/F, tanφ/F) (eqs. F3–F6): A's two
    equations give its base force N_A and the interface force Q = q/D (Cramer's rule); P's
    two equations in its one unknown N_P leave the residual b × r_P, zero at limit
    equilibrium. It is returned times D, g(F) = D·(b × r_P): a polynomial in 1/F, continuous
    where D passes through zero (there Q is infinite and b × r_P jumps sign without a root).
    ``blocks`` holds the weights, directions, lengths and strengths (`two_block_data`).
    Returns (g [N²/m²], forces N_A, N_P, Q [N/m])."""
    d = blocks
    mu = {k: math.tan(math.radians(d["friction"])) / reduction for k in ("A", "P", "J")}
    cr = d["cohesion"] / reduction
    w_a, w_p = np.array([0.0, -d["weight_A"]]), np.array([0.0, -d["weight_P"]])
    a1 = d["n_A"] - mu["A"] * d["d_A"]
    a2 = d["m"] - mu["J"] * d["s"]
    r_a = -w_a + cr * d["L_A"] * d["d_A"] + cr * d["L_J"] * d["s"]
    det = _cross(a1, a2)
    q_det = _cross(a1, r_a)                                                        # Q·D
    b1 = d["n_P"] - mu["P"] * d["d_P"]
    r_p_det = det * (-w_p + cr * d["L_P"] * d["d_P"] - cr * d["L_J"] * d["s"]) + q_det * a2   # r_P·D
    g = _cross(b1, r_p_det)
    if det == 0.0:
        return g, dict(N_A=math.nan, N_P=math.nan, Q=math.nan)
    return g, dict(N_A=_cross(r_a, a2) / det, N_P=float(r_p_det @ b1) / float(b1 @ b1) / det, Q=q_det / det)


def _singular(reduction: float, blocks: dict) -> bool:
    """A's equations are singular at this F: its base and interface reactions are parallel
    (D = a₁ × a₂ ≈ 0 relative to |a₁||a₂|)."""
    d = blocks
    mu = math.tan(math.radians(d["friction"])) / reduction
    a1, a2 = d["n_A"] - mu * d["d_A"], d["m"] - mu * d["s"]
    return abs(_cross(a1, a2)) <= 1e-6 * float(np.linalg.norm(a1) * np.linalg.norm(a2))


def two_block_data(case: str = "bilinear", **options) -> dict:
    """The numbers the two-block closed form needs, from a case's geometry: weights W_A, W_P
    [N/m]; A's sliding direction d_A (down the bedding) and base normal n_A; P's d_P (along J1,
    out of the face) and n_P; J2's normal m (into A) and the unit relative slip s of A against
    P, from the compatibility (v_A − v_P)·m = 0 (eq. F2); the lengths L_A, L_P, L_J [m]; φ, c."""
    if case not in ("ploughing", "bilinear"):
        raise ValueError(f"two_block_data: the case must be 'ploughing' or 'bilinear', got {case!r}")
    geo = geometry(case, **options)
    p = geo["params"]
    gamma = DENSITY * G
    psi = math.radians(p["dip"])
    d_a = np.array([math.cos(psi), -math.sin(psi)])
    n_a = np.array([math.sin(psi), math.cos(psi)])
    d_p = (geo["F"] - geo["B"]) / np.linalg.norm(geo["F"] - geo["B"])   # out along J1
    n_p = np.array([-d_p[1], d_p[0]])                                   # J1's normal, up into P
    j = (geo["G"] - geo["C"]) / np.linalg.norm(geo["G"] - geo["C"])
    m = np.array([j[1], -j[0]])                                         # J2's normal ...
    if float(m @ (geo["A"].mean(axis=0) - geo["C"])) < 0:
        m = -m                                                          # ... into A
    speed_p = float(d_a @ m) / float(d_p @ m)                           # |v_P| / |v_A| (F2)
    rel = d_a - speed_p * d_p
    return dict(weight_A=gamma * _area(geo["A"]), weight_P=gamma * _area(geo["P"]), d_A=d_a, n_A=n_a,
                d_P=d_p, n_P=n_p, m=m, s=rel / np.linalg.norm(rel), speed_ratio=speed_p,
                L_A=float(np.linalg.norm(geo["K"] - geo["C"])), L_P=float(np.linalg.norm(geo["F"] - geo["B"])),
                L_J=float(np.linalg.norm(geo["G"] - geo["C"])), friction=p["friction"], cohesion=p["cohesion"])


def two_block_fs(case: str = "bilinear", **options) -> float:
    """FS of the two-block mechanism (ploughing or bilinear): the root F of g(F) = 0 whose
    forces N_A, N_P, Q are all compressive (eqs. F3–F7). g is scanned on a fine logarithmic
    grid of F from 0.01 to 100 and each sign change refined by bisection; the smallest root
    with admissible forces is the FS. Raises ValueError if there is none."""
    data = two_block_data(case, **options)
    grid = np.exp(np.linspace(math.log(0.01), math.log(100.0), 4001))
    g = np.array([two_block_residual(f, data)[0] for f in grid])
    for i in range(len(grid) - 1):
        if not (np.isfinite(g[i]) and np.isfinite(g[i + 1])) or g[i] * g[i + 1] > 0:
            continue
        lo, hi, glo = grid[i], grid[i + 1], g[i]
        for _ in range(100):
            mid = math.sqrt(lo * hi)
            gm = two_block_residual(mid, data)[0]
            if (gm > 0) == (glo > 0):
                lo, glo = mid, gm
            else:
                hi = mid
        root = math.sqrt(lo * hi)
        forces = two_block_residual(root, data)[1]
        if _singular(root, data):
            continue  # D = 0 and Q·D = 0 together: a 0/0 point of Q, not a limit state (F7)
        if min(forces.values()) >= 0.0:
            return root
    raise ValueError(f"footwall {case}: the two-block mechanism has no limit equilibrium with compressive "
                     f"forces for F in [0.01, 100]")


def rigid_fs(case: str = "bilinear", **options) -> float:
    """The group glued into one rigid body (the original KGM's answer): the planar slab is
    eq. F1; the bilinear pair can only slide out on J1 (the bedding opens):
    FS = (c·L_P + W cosβ tanφ)/(W sinβ), W = W_A + W_P (eq. F8); the ploughing pair has no
    rigid mode (sliding on the bedding would cut into J1, sliding on J1 goes up it): inf."""
    if case == "planar":
        p = {**DEFAULTS["planar"], **options}
        return planar_fs(**p)
    if case == "ploughing":
        return math.inf
    data = two_block_data(case, **options)
    beta = math.atan2(-data["d_P"][1], data["d_P"][0])
    w = data["weight_A"] + data["weight_P"]
    return ((data["cohesion"] * data["L_P"] + w * math.cos(beta) * math.tan(math.radians(data["friction"])))
            / (w * math.sin(beta)))


def turning_fs(case: str = "bilinear", **options) -> float:
    """The bilinear pair turning as one body (docs/kgm/footwall.md §9, eq. F9): the slab's upper
    end K slides down the bedding and the kink B out along J1, every other face opens, about
    the instantaneous centre O where the bedding's normal through K meets J1's normal through
    B. At the strength tanφ/F (no cohesion: a point has no length) the rock pushes on K with
    N_K·(n_A − μ·t_K) and on B with N_B·(n_P − μ·t_B), t the points' slip directions; the force
    balance with the weight W = W_A + W_P gives N_K, N_B, and the moment about O (the normal
    forces pass through O) W's moment + Σ (p − O) × (−μ N t) = 0 gives F: the least root with
    N_K, N_B ≥ 0, on the grid of `two_block_fs`. Raises ValueError if there is none."""
    if case != "bilinear":
        raise ValueError(f"turning_fs: the case must be 'bilinear', got {case!r}")
    geo = geometry(case, **options)
    d = two_block_data(case, **options)
    area_p, area_a = _area(geo["P"]), _area(geo["A"])
    centre_of_mass = (area_p * _centroid(geo["P"]) + area_a * _centroid(geo["A"])) / (area_p + area_a)
    weight = np.array([0.0, -(d["weight_A"] + d["weight_P"])])
    pts, nrm = np.array([geo["K"], geo["B"]]), np.array([d["n_A"], d["n_P"]])
    a, _ = np.linalg.solve(np.column_stack([nrm[0], -nrm[1]]), pts[1] - pts[0])
    o = pts[0] + a * nrm[0]
    drive = _cross(centre_of_mass - o, weight)           # the weight's moment about O
    omega = 1.0 if drive > 0 else -1.0
    slip = np.array([omega * np.array([-(p - o)[1], (p - o)[0]]) for p in pts])
    slip /= np.linalg.norm(slip, axis=1, keepdims=True)
    tan_phi = math.tan(math.radians(d["friction"]))

    def residual(f: float) -> tuple[float, np.ndarray]:
        cols = nrm - (tan_phi / f) * slip
        n = np.linalg.solve(cols.T, -weight)
        return omega * (drive + sum(_cross(pts[k] - o, -(tan_phi / f) * n[k] * slip[k]) for k in range(2))), n

    grid = np.exp(np.linspace(math.log(0.01), math.log(100.0), 4001))
    g = [residual(f)[0] for f in grid]
    for i in range(len(grid) - 1):
        if not g[i] < 0.0 <= g[i + 1]:
            continue
        lo, hi = grid[i], grid[i + 1]
        for _ in range(100):
            mid = math.sqrt(lo * hi)
            lo, hi = (mid, hi) if residual(mid)[0] < 0.0 else (lo, mid)
        root = math.sqrt(lo * hi)
        if np.all(residual(root)[1] >= 0.0):
            return root
    raise ValueError(f"footwall {case}: the pair has no turning limit with compressive forces for F in [0.01, 100]")


def _centroid(xy: np.ndarray) -> np.ndarray:
    x, y = xy[:, 0], xy[:, 1]
    c = x * np.roll(y, -1) - np.roll(x, -1) * y
    return np.array([((x + np.roll(x, -1)) * c).sum(), ((y + np.roll(y, -1)) * c).sum()]) / (3.0 * c.sum())


def closed_form_fs(case: str = "bilinear", **options) -> float:
    """The limit-equilibrium FS of a case: eq. F1 (planar) or the two-block root (F3–F7)."""
    if case == "planar":
        return planar_fs(**{**DEFAULTS["planar"], **options})
    return two_block_fs(case, **options)


if __name__ == "__main__":
    from ddatai.cli import run_as_script

    run_as_script(build, DURATION, "footwall")
