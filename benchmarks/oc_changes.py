"""Why ntdda's grid takes ddatai more solves a step than ntdda: every extra solve of the open–close
iteration on the grid of docs/ntdda.md §5.1, what changed, and what ntdda's rules would save.

    python benchmarks/oc_changes.py [--blocks 16] [--steps 2000] [--rules all|none|LIST]

The grid's DDAML files are written by ``ntdda_beside.grid_files`` and run by the NumPy path
(``dd.read_ntdda``, ``Params(kernels="numpy", initial_equilibrium=False)``: ntdda's sudden start,
the same iteration as the fused engine). A hook around `ddatai.open_close.judge` records, for each
solve, the contacts that `contact_law.violations` marks (block pair, vertex–edge or vertex–vertex,
old and new state, penetration or gap, shear force against its Coulomb strength, which test) and
whether the judgement changed any contact's state at all; a hook on `Stepper.attempt` tells the
step's first try from the retake of a plastic impact (`ddatai.impacts`). Prints the breakdown of
the solves beyond one a step.

``--rules`` then re-runs the grid with each of ntdda's rules put in by monkeypatching (never part
of ddatai; they change results) and prints solves a step, the time the 2,000 steps reach and how
far the blocks end from the unchanged run:

- ``noimpact``: no approach bound and no plastic-impact retake (``Params.impact_overshoot=None``);
- ``noslip``: a lock ↔ slide change is applied but does not call another solve (ntdda counts only
  open ↔ closed changes);
- ``reopen``: a closed contact opens only past a gap of 2e-7·w0 (ntdda's ``Opencriteria``);
- ``reclose``: an open contact closes only past a penetration of 2e-4·w0 (ntdda's ``Openclose``;
  ``reclose=1e-6`` another fraction of w0);
- ``stale``: a locked contact that the law keeps locked with the last solve's normal force although
  it holds more than this solve's Coulomb strength slides at once (no solve with its state
  unchanged).
"""

from __future__ import annotations

import argparse
import collections
import dataclasses
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

import ddatai as dd  # noqa: E402
from ddatai import open_close as oc  # noqa: E402
from ddatai import step as st  # noqa: E402
from ddatai.contact_law import Judgement  # noqa: E402
from ddatai.layout import KIND, LOCK, OPEN, SLIDE, VV  # noqa: E402
from ddatai.model import build_model  # noqa: E402
from ntdda_beside import grid_files  # noqa: E402

NAME = {OPEN: "open", LOCK: "lock", SLIDE: "slide"}
RULES = ("noimpact", "noslip", "reopen", "stale", "noimpact,noslip,reopen", "noimpact,noslip,reopen,reclose",
         "reclose")


def run(case, rules: frozenset = frozenset(), record: bool = False):
    """The grid's 2,000 steps on the NumPy path with ``rules`` (module docstring) patched in;
    returns (Results, the solve log when ``record``). The patches are undone on return."""
    kw = dict(kernels="numpy", initial_equilibrium=False)
    if "noimpact" in rules:
        kw["impact_overshoot"] = None
    params = dataclasses.replace(case.params, **kw)
    log, where = [], dict(step=0, attempt=0)
    violations0, judge0, attempt0, advance0 = oc.violations, oc.judge, st.Stepper.attempt, st.Stepper.advance
    reclose = [r for r in rules if r.startswith("reclose")]

    def violations(model, contacts, law, block_load):
        bad = violations0(model, contacts, law, block_load)
        if "reopen" in rules:
            bad &= ~((contacts.state != OPEN) & (law.state == OPEN) & (law.dn < 2e-7 * model.w0))
        if reclose:
            share = float(reclose[0].split("=")[1]) if "=" in reclose[0] else 2e-4
            bad &= ~((contacts.state == OPEN) & (law.dn > -share * model.w0))
        if "stale" in rules:
            law.state[bad & (contacts.state == LOCK) & (law.state == LOCK) & law.closed] = SLIDE
        return bad

    def judge(model, contacts, law, bad, break_bonds=True, couple=True):
        before = [contacts.state.copy(), contacts.line.copy(), contacts.shear_dir.copy(), contacts.coupled.copy()]
        flip = bad & ((contacts.state == OPEN) != (law.state == OPEN))
        rows = []
        if record:
            vv = contacts.cint[:, KIND] == VV
            for i in np.flatnonzero(bad):
                rows.append((int(contacts.block_a[i]), int(contacts.block_b[i]), bool(vv[i]), int(contacts.state[i]),
                             int(law.state[i]), float(law.dn[i]), float(law.ft_now[i]), float(law.strength[i])))
        out = judge0(model, contacts, law, bad, break_bonds, couple)
        if "noslip" in rules and out.changed and not flip.any():
            closed_ve = (contacts.state != OPEN) & (contacts.cint[:, KIND] != VV)
            out = Judgement(changed=False, bad=np.zeros_like(bad), friction=law.friction_now,
                            coulomb=float(np.max((np.abs(law.ft_now) - law.strength)[closed_ve], initial=0.0)))
        if record:
            after = [contacts.state, contacts.line, contacts.shear_dir, contacts.coupled]
            log.append(dict(step=where["step"], attempt=where["attempt"], changed=out.changed, rows=rows,
                            same=all(np.array_equal(a, b) for a, b in zip(before, after))))
        return out

    def attempt(self, *args, **kwargs):
        where["attempt"] += 1
        return attempt0(self, *args, **kwargs)

    def advance(self, state, t_end=None):
        where["step"], where["attempt"] = state.step + 1, 0
        return advance0(self, state, t_end)

    oc.violations, oc.judge, st.Stepper.attempt, st.Stepper.advance = violations, judge, attempt, advance
    try:
        res = dd.simulate(case.scene, params, steps=STEPS, record_every=STEPS)
    finally:
        oc.violations, oc.judge, st.Stepper.attempt, st.Stepper.advance = violations0, judge0, attempt0, advance0
    return res, log


def breakdown(res, log, w0: float) -> None:
    """Print where the solves beyond one a step went (module docstring)."""
    s = res.steps
    n = len(s)
    total, first = int(s["oc_total"].sum()), int(s["oc_iterations"].sum())
    print(f"steps {n}  solves {total} ({total / n:.4f} a step)  accepted tries' solves {first}  "
          f"dt cuts {int(s['dt_cuts'].sum())}  steps shortened by the approach bound "
          f"{int(np.sum(s['dt'] < 0.999 * np.max(s['dt'])))}  time reached {float(s['time'][-1]):.4f} s")
    retaken = {r["step"] for r in log if r["attempt"] > 1}
    retake_solves = sum(1 for r in log if r["attempt"] > 1)
    print(f"impact retakes: {len(retaken)} steps, {retake_solves} solves ({retake_solves / n:.4f} a step; "
          f"each also one solve of the impact projection with the last factor, not in oc_total)")
    kinds = collections.Counter()
    for r in log:
        if not r["changed"]:
            continue
        flips = [c for c in r["rows"] if (c[3] == OPEN) != (c[4] == OPEN)]
        if r["same"]:
            kind = "no state changed (a locked contact judged locked with the last solve's N)"
        elif flips:
            outside = any((c[3] == OPEN and -c[5] > 2e-4 * w0) or (c[3] != OPEN and c[5] > 2e-7 * w0) for c in flips)
            kind = "open<->closed, " + ("some outside ntdda's band" if outside else "all inside ntdda's band")
        else:
            kind = "lock<->slide only"
        kinds[("first try" if r["attempt"] == 1 else "impact retake", kind)] += 1
    for (tries, kind), count in sorted(kinds.items()):
        print(f"  {tries:13s} {kind:72s} {count:5d} ({count / n:.4f} a step)")
    changes = [(c, r["step"]) for r in log if r["changed"] for c in r["rows"]]
    moves = collections.Counter((NAME[c[3]], NAME[c[4]], "vv" if c[2] else "ve") for c, _ in changes)
    print("contact changes:", ", ".join(f"{a}>{b} {k} {v}" for (a, b, k), v in moves.most_common()))
    close = np.array([-c[5] for c, _ in changes if c[3] == OPEN and c[4] != OPEN])
    gap = np.array([c[5] for c, _ in changes if c[3] != OPEN and c[4] == OPEN])
    slip = np.array([(abs(c[6]) - c[7]) / max(c[7], 1e-12) for c, _ in changes if c[3] == LOCK and c[4] == SLIDE])
    if len(close):
        print(f"open->closed at penetration median {np.median(close):.3g} m, max {close.max():.3g} m "
              f"(ntdda closes past 2e-4·w0 = {2e-4 * w0:.3g} m)")
    if len(gap):
        print(f"closed->open at gap median {np.median(gap):.3g} m, max {gap.max():.3g} m "
              f"(ntdda opens past 2e-7·w0 = {2e-7 * w0:.3g} m; {np.mean(gap > 2e-7 * w0):.0%} beyond)")
    if len(slip):
        print(f"lock->slide at |shear| / Coulomb strength − 1: median {np.median(slip):.3g}")
    pairs = collections.Counter((c[0], c[1], "vv" if c[2] else "ve") for c, _ in changes)
    print("pairs changing most:", ", ".join(f"{a}-{b} {k} {v}" for (a, b, k), v in pairs.most_common(8)))
    extra = np.zeros(n + 1)
    for r in log:
        if r["changed"] or r["attempt"] > 1:
            extra[r["step"]] += 1
    x = extra[1:] - extra[1:].mean()
    ac = np.correlate(x, x, "full")[len(x) - 1:]
    lag = int(np.argmax(ac[20:n // 3])) + 20
    print(f"extra solves a 10-step window, steps 1–300: {extra[1:301].reshape(-1, 10).sum(1).astype(int).tolist()}")
    print(f"period of the extra solves (autocorrelation peak): {lag} steps")


def main() -> None:
    global STEPS
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--blocks", default="16", help="grid sizes, comma-separated (1, 4, 16, 64)")
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--rules", default="all", help="'all', 'none' or ';'-separated sets like noimpact,noslip")
    a = ap.parse_args()
    STEPS = a.steps
    with tempfile.TemporaryDirectory(prefix="oc_changes_") as tmp:
        for blocks in (int(b) for b in a.blocks.split(",")):
            geo, ana = grid_files(blocks, Path(tmp), a.steps)
            case = dd.read_ntdda(geo, ana)
            w0 = build_model(case.scene, dataclasses.replace(case.params, kernels="numpy",
                                                             initial_equilibrium=False)).w0
            print(f"== {blocks} blocks (w0 = {w0:g} m)")
            t = time.process_time()
            base, log = run(case, record=True)
            print(f"(CPU {time.process_time() - t:.1f} s)")
            breakdown(base, log, w0)
            end = np.asarray(base.centroid[-1])
            sets = RULES if a.rules == "all" else () if a.rules == "none" else a.rules.split(";")
            for rule in sets:
                res, _ = run(case, frozenset(rule.split(",")))
                s, c = res.steps, np.asarray(res.centroid[-1])
                drift = float(np.max(np.abs(c - np.asarray(res.centroid[0]))[:, 0]))
                print(f"  rules {rule:34s} solves/step {s['oc_total'].mean():.4f}  time {float(s['time'][-1]):.4f} s  "
                      f"end vs unchanged {float(np.max(np.linalg.norm(c - end, axis=1))):.3g} m  "
                      f"largest sideways drift {drift:.3g} m", flush=True)


STEPS = 2000
if __name__ == "__main__":
    main()
