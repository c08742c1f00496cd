"""An n × n grid of perfectly fitted unit blocks on a fixed base (aligned columns).

Every block starts in edge-to-edge contact with its neighbours, so the grid carries the full
contact set from the first step: the base of the block-count scaling benchmark. Static by
default (velocities reset each step), which settles the grid without ringing; a dynamic run
shows the elastic oscillation of the columns that sudden gravity excites.
Run ``python scenes/stacked_grid.py``.
"""

import ddatai as dd

DURATION = 0.2  # s


def build(n: int = 20, friction: float = 30.0, static: bool = True, dt: float = 0.005):
    """Returns (scene, params): n × n unit blocks (1 m) on a fixed base, joints with φ = friction."""
    scene = dd.Scene(gravity=9.81)
    rock = dd.Material(density=2500.0, young=5e9, poisson=0.25)
    scene.add_block([(-1, -1), (n + 1, -1), (n + 1, 0), (-1, 0)], material=rock, fixed=True)
    for j in range(n):
        for i in range(n):
            scene.add_block([(i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1)], material=rock)
    scene.set_joint(dd.Joint(friction=friction))
    return scene, dd.Params(static=static, dt=dt)


def main(duration: float = DURATION) -> dd.Results:
    scene, params = build()
    res = dd.simulate(scene, params=params, duration=duration, record_every=10)
    s = res.summary()
    n = round((scene.n_blocks - 1) ** 0.5)
    sy = res.stress[-1, 1:, 1].reshape(n, n).mean(axis=1)
    exact = -2500.0 * 9.81 * (n - 0.5)
    print(f"{s['blocks']} blocks, {s['steps']} steps, {s['dt_cuts']} dt cuts, "
          f"{s['oc_iterations']} open-close iterations, {s['wall_time']:.2f} s in the solver")
    print(f"bottom row mean σy = {sy[0] / 1e3:.2f} kPa (equilibrium {exact / 1e3:.2f} kPa)")
    return res


if __name__ == "__main__":
    main()
