"""What the open–close iteration of a large failing model does, solve by solve: how many
contacts change state and how, which of them flip back, and how the count depends on Δt.

    python benchmarks/oc_diagnosis.py [--family slope] [--size 391] [--steps 4] [--dt 1e-3,5e-4]
                                      [--params NAME=VALUE,...]

After the equilibrium stage (the settled protocol of ``benchmarks/scaling.py``; the settled state
is kept in ``--cache`` so that each Δt starts from the same state), one untimed step, then
``--steps`` steps at each Δt (a fixed ``Params.dt``). For each solve of each step it counts the
contacts `contact_law.judge` changes, by kind of change:

- ``o>c``: open → closed (locked or sliding), ``c>o``: closed → open;
- ``l>s`` / ``s>l``: locked → sliding / sliding → locked (a sliding contact whose slip turns
  round locks first, Shi's rule);
- ``line``: a vertex–vertex contact changing its entrance line, state kept;
- ``force``: marked (`contact_law.violations`) with its state kept: a sliding contact whose
  friction is not N·tanφ of this solve (it takes the friction of the same solve from then on);

the contacts that flip back (a contact whose state returns to one it had earlier in the step),
and by how much each change's contact misses the law: the overlap of an open contact that the
law closes, as a share of the penetration limit. Prints a line per step and a summary; with Δt
the CPU time per simulated second.
"""

from __future__ import annotations

import dataclasses
import pickle
import sys
import time
from collections import Counter
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from scaling_scenes import case_parser, case_scene, use_checkout  # noqa: E402

use_checkout()


def main() -> None:
    import ddatai as dd
    import ddatai.open_close as oc
    from ddatai.layout import KIND, LOCK, OPEN, SLIDE, VV
    from ddatai.start import settle
    from ddatai.step import Stepper

    ap = case_parser(__doc__)
    ap.add_argument("--dt", default="", help="fixed Δt values to compare (default: the scene's)")
    ap.add_argument("--cache", type=Path, default=Path("/tmp"))
    a = ap.parse_args()
    scene, params = case_scene(a)
    cache = a.cache / f"oc_diagnosis_{a.family}{a.size}.pkl"
    if cache.exists():
        state = pickle.loads(cache.read_bytes())
    else:
        model = dd.build_model(scene, params)
        state, start = settle(Stepper(model), model.initial_state())
        print(f"stage: held {start.held}, released {start.released}, welded {bool(start.welded)}")
        cache.write_bytes(pickle.dumps(state))

    log: list = []
    judge = oc.judge

    def recording(model, contacts, law, bad, *args, **kw):
        before = contacts.state.copy(), contacts.line.copy()
        overlap = np.where(bad & (contacts.state == OPEN) & law.closed, -law.dn, 0.0) / model.penetration_limit
        verdict = judge(model, contacts, law, bad, *args, **kw)
        log.append((before, contacts.state.copy(), contacts.line.copy(), bad.copy(), overlap,
                    contacts.cint[:, KIND] == VV))
        return verdict

    oc.judge = recording
    for dt in [float(x) for x in a.dt.split(",") if x] or [params.dt]:
        model = dd.build_model(scene, dataclasses.replace(params, dt=dt))
        stepper = Stepper(model)
        s = state
        s, _ = stepper.step(s)  # untimed, as scaling.py's warm-up
        totals, cpu, sim = Counter(), 0.0, 0.0
        solves, flips, per_solve = [], [], []
        for _ in range(a.steps):
            log.clear()
            t = time.process_time()
            s, record = stepper.step(s)
            cpu += time.process_time() - t
            sim += record.dt
            kinds = []
            seen = {}
            back = 0
            for before, after, line, bad, overlap, vv in log:
                b, f = before[0], after
                c = Counter()
                c["o>c"] = int(np.count_nonzero((b == OPEN) & (f != OPEN)))
                c["c>o"] = int(np.count_nonzero((b != OPEN) & (f == OPEN)))
                c["l>s"] = int(np.count_nonzero((b == LOCK) & (f == SLIDE)))
                c["s>l"] = int(np.count_nonzero((b == SLIDE) & (f == LOCK)))
                c["line"] = int(np.count_nonzero((b == f) & (before[1] != line)))
                c["force"] = int(np.count_nonzero(bad & (b == f) & (before[1] == line)))
                shallow = overlap[overlap > 0]
                c["o>c<1%lim"] = int(np.count_nonzero(shallow < 0.01))
                changed = np.flatnonzero(b != f)
                for k in changed:  # contacts whose state returns to one they had in the step
                    hist = seen.setdefault(int(k), [int(b[k])])
                    if int(f[k]) in hist:
                        back += 1
                    hist.append(int(f[k]))
                kinds.append(c)
                totals.update(c)
            multi = sum(1 for h in seen.values() if len(h) > 2)
            solves.append(record.oc_total)
            flips.append(back)
            per_solve.append(kinds)
            print(f"dt {record.dt:.2e} solves {record.oc_total:2d} (oc {record.oc_iterations}, cuts {record.dt_cuts}) "
                  f"contacts {record.contacts:,} closed {record.closed:,}; flip-backs {back}, contacts changed "
                  f">1x {multi} of {len(seen)}")
            print("   per solve (o>c c>o l>s s>l line force): " + " | ".join(
                f"{c['o>c']} {c['c>o']} {c['l>s']} {c['s>l']} {c['line']} {c['force']}" for c in kinds))
        print(f"dt {dt:.2e}: {np.mean(solves):.2f} solves a step, CPU {cpu / a.steps * 1e3:.0f} ms a step, "
              f"{cpu / sim:.1f} CPU s per simulated s; totals {dict(totals)}; flip-backs {sum(flips)}")


if __name__ == "__main__":
    main()
