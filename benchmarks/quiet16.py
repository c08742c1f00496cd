"""Why ntdda's 16-block grid takes one solve a step and ddatai 1.49: both codes' contact states step by
step on the same DDAML files, and how robust ntdda's count is.

    benchmarks/ntdda_beside/build.sh NTDDA_CHECKOUT      # builds contact_log beside step_timer
    python benchmarks/quiet16.py --driver /tmp/ntdda-beside-build/contact_log
                                 [--blocks 16] [--parts trace,extra,closings,beta,perturb]
                                 [--sizes 4,16,64] [--ddatai-perturb]

The grid of docs/ntdda.md §5.1 written as DDAML files by ``ntdda_beside.grid_files``, 2,000 steps
from ntdda's sudden start, one thread in both codes. Parts:

- ``trace``: ntdda's analysis through our ``contact_log`` driver (``step_timer.c`` with ntdda's
  contact judge ``df22`` wrapped, ``benchmarks/ntdda_beside/contact_log.c``: every contact's state and
  normal distance after every solve, every block's centroid at every step; no ntdda file changed)
  beside ddatai's NumPy path (``Params(kernels="numpy", initial_equilibrium=False)``) with its own
  rules and with ntdda's rules monkeypatched in (``oc_changes.run``: no approach bound or impact
  retake, lock ↔ slide changes not solved again, a closed contact opens only past 2e-7·w0 of gap, an
  open one closes only past 2e-4·w0 of overlap; never part of ddatai). A hook on ``Stepper.accept``
  keeps each step's accepted contacts. Printed by contact class (contacts with the base block, bed
  joints between a block and the one above it, head joints between neighbours in a row, corner
  vertex–vertex contacts): how many are closed, the deepest overlap, how many are open while their
  blocks overlap; ntdda's largest open overlap against its re-closing band; each code's solves a
  step; how far ddatai's centroids lie from ntdda's, step by step.
- ``extra``: ddatai's solves that changed contact states (``oc_changes.run``'s log), by the
  classes of the contacts that changed (the impact rule's retakes apart), with and without the
  impact rule.
- ``closings``: for each of ``--sizes``, ntdda's open → closed changes (how many, the first step,
  the median overlap at closing), closed → open changes and the steps with more than one solve,
  against its re-closing band 2e-4·w0 (w0 grows with the grid).
- ``beta``: ddatai's solves a step with ntdda's integrator (Newmark β = ½, γ = 1; ddatai's default
  β = 9/16), with and without the impact rule.
- ``perturb``: ntdda's open–close iterations a step and its largest sideways offset of a block
  after 2,000 steps with Young's modulus ×0.95 … ×1.05 and the joint friction 29.5° … 30.5° (one
  input changed at a time in the analysis file); ``--ddatai-perturb`` also runs ddatai (NumPy path)
  on a few of those files.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

import ddatai as dd  # noqa: E402
from ddatai import step as st  # noqa: E402
from ddatai.layout import KIND, VV  # noqa: E402
from ddatai.model import build_model  # noqa: E402
import oc_changes  # noqa: E402
from ntdda_beside import PINNED, grid_files  # noqa: E402

STEPS = 2000
NTDDA_RULES = "noimpact,noslip,reopen,reclose"  # oc_changes.run's names for ntdda's four rules
SHOW = (1, 4, 7, 10, 13, 16, 22, 28, 40, 52, 80, 96, 100, 120, 140, 200, 300, 500, 1000, 1500, 2000)
CLASSES = ("base", "bed", "head", "corner")


@dataclasses.dataclass
class Trace:
    """One run's accepted contacts, step by step (ddatai's block numbers, the base block 0)."""
    steps: dict          # step -> dict(a, b, vv, closed, dn) of the accepted solve
    solves: np.ndarray   # solves a step (ntdda: open-close iterations)
    centroid: np.ndarray  # (steps + 1, blocks, 2) block centroids at each step's end [m]
    raw: np.ndarray | None = None  # ntdda: every logged row (contact_log.c's columns)


def ntdda_run(driver: str, geo: Path, ana: Path, log: Path | None = None) -> dict:
    """ntdda's analysis of ``geo`` + ``ana`` in a fresh process (our driver's JSON line); with ``log``
    the contact_log driver writes its contact log there."""
    env = {**os.environ, **PINNED}
    if log is not None:
        env["NTDDA_CONTACT_LOG"] = str(log)
    with tempfile.TemporaryDirectory(prefix="quiet16_") as cwd:
        proc = subprocess.run([driver, str(geo), str(ana)], capture_output=True, text=True, cwd=cwd, env=env,
                              timeout=3600)
    if proc.returncode != 0:
        raise RuntimeError(f"ntdda driver failed ({proc.returncode}): {proc.stderr[-2000:]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def read_contact_log(path: Path, final: np.ndarray) -> Trace:
    """The contact_log driver's file as a `Trace`: each step's last solve, ntdda's blocks − 1;
    ``final``: the centroids at the end of the run (the driver's JSON line)."""
    rows, cents = [], {}
    with open(path) as f:
        for line in f:
            if line.startswith("C"):
                parts = line.split()
                cents[int(parts[1])] = np.array(parts[2:], float).reshape(-1, 2)
            else:
                rows.append(line.split())
    d = np.array(rows, float)
    step, solve = d[:, 0].astype(int), d[:, 1].astype(int)
    last = np.zeros(int(step.max()) + 1, int)
    np.maximum.at(last, step, solve)
    keep = solve == last[step]
    steps = {}
    for s in np.unique(step):
        r = keep & (step == s)
        steps[int(s)] = dict(a=d[r, 4].astype(int) - 1, b=d[r, 5].astype(int) - 1, vv=d[r, 3] == 1,
                             closed=d[r, 7] > 0, dn=d[r, 9])
    n = int(step.max())
    # a step's first solve logs the centroids at its start: the end of the step before
    centroid = np.array([cents[s] for s in range(1, n + 1)] + [final])
    return Trace(steps=steps, solves=last[1:], centroid=centroid, raw=d)


def ntdda_openings(trace: Trace, start: np.ndarray) -> None:
    """How ntdda's contacts left the closed state, class by class: by its gap test within a step
    (df22: the steps and gaps), or between steps (closed at a step's end, fewer closed at the
    next step's start: a contact found again as a new one starts open)."""
    d = trace.raw
    step, solve = d[:, 0].astype(int), d[:, 1].astype(int)
    a, b = d[:, 4].astype(int) - 1, d[:, 5].astype(int) - 1
    cls = classes(dict(a=a, b=b, vv=d[:, 3] == 1), start)
    last = solve == trace.solves[step - 1]
    n = len(trace.solves)
    for k, m in cls.items():
        opened = m & (d[:, 6] > 0) & (d[:, 7] == 0)
        closed_end = np.bincount(step[m & last & (d[:, 7] > 0)], minlength=n + 2)
        closed_start = np.bincount(step[m & (solve == 1) & (d[:, 6] > 0)], minlength=n + 2)
        lost = closed_end[1:n] - closed_start[2:n + 1]
        gaps = d[opened, 9] * 1e6
        where = f" at steps {sorted(set(step[opened].tolist()))}, gaps {gaps.min():.2f}–{gaps.max():.2f} µm" \
            if opened.any() else ""
        print(f"ntdda {k}: opened by the gap test {int(opened.sum())}{where}; closed states lost between steps "
              f"{int(lost[lost > 0].sum())} (steps {(np.flatnonzero(lost > 0) + 1).tolist()[:10]}), gained "
              f"{int(-lost[lost < 0].sum())}; closings {int((m & (d[:, 6] == 0) & (d[:, 7] > 0)).sum())}")


def ddatai_trace(case, rules: str = "", **params) -> Trace:
    """ddatai's NumPy path on ``case`` with ntdda's ``rules`` patched in (``oc_changes.run``) and
    ``params`` changed; each step's accepted contacts kept by a hook on ``Stepper.accept``."""
    case = dataclasses.replace(case, params=dataclasses.replace(case.params, **params))
    model = build_model(case.scene, dataclasses.replace(case.params, kernels="numpy", initial_equilibrium=False))
    steps, ends, where = {}, {}, {"step": 0}
    advance0, accept0 = st.Stepper.advance, st.Stepper.accept

    def advance(self, state, t_end=None):
        where["step"] = state.step + 1
        return advance0(self, state, t_end)

    def accept(self, state, geom, contacts, vec, oc, start_dn=None):
        attempt = accept0(self, state, geom, contacts, vec, oc, start_dn)
        if attempt.ok:  # the last accepted try of a step is the one kept (an impact's retake)
            c = attempt.contacts
            steps[where["step"]] = dict(a=c.block_a.copy(), b=c.block_b.copy(), vv=c.cint[:, KIND] == VV,
                                        closed=c.state != 0, dn=c.dn.copy())
            xy = attempt.vertex_xy
            ends[where["step"]] = np.array([xy[model.vertex_block == k].mean(0) for k in range(model.n_blocks)])
        return attempt

    st.Stepper.advance, st.Stepper.accept = advance, accept
    oc_changes.STEPS = STEPS
    try:
        res, _ = oc_changes.run(case, frozenset(r for r in rules.split(",") if r))
    finally:
        st.Stepper.advance, st.Stepper.accept = advance0, accept0
    start = np.asarray(res.centroid[0])
    centroid = np.array([start] + [ends[s] + model.origin for s in range(1, len(res.steps) + 1)])
    return Trace(steps=steps, solves=np.asarray(res.steps["oc_total"]), centroid=centroid)


def classes(step: dict, start: np.ndarray) -> dict:
    """Masks of the contact classes (module docstring) from the blocks' start centroids."""
    a, b = step["a"], step["b"]
    base = (a == 0) | (b == 0)
    same_row = np.abs(start[a, 1] - start[b, 1]) < 0.5
    same_column = np.abs(start[a, 0] - start[b, 0]) < 0.5
    return dict(base=base, bed=~base & same_column & ~step["vv"], head=~base & same_row & ~step["vv"],
                corner=step["vv"] & ~base)


def state_table(name: str, trace: Trace, start: np.ndarray) -> None:
    """Closed / all, the deepest overlap [µm] and the open contacts that overlap, class by class."""
    print(f"\n{name}: solves a step {trace.solves.mean():.4f}")
    print("| step | solves | " + " | ".join(f"{k}: closed, deepest µm, open & overlapping" for k in CLASSES) + " |")
    for s in SHOW:
        if s not in trace.steps:
            continue
        step = trace.steps[s]
        cells = []
        for k, m in classes(step, start).items():
            over = m & ~step["closed"] & (step["dn"] < 0)
            cells.append(f"{int(step['closed'][m].sum())}/{int(m.sum())}, {-1e6 * step['dn'][m].min():.1f}, "
                         f"{int(over.sum())}")
        print(f"| {s} | {trace.solves[s - 1]} | " + " | ".join(cells) + " |")


def open_overlaps(name: str, trace: Trace, start: np.ndarray, band: float, since: int = 50) -> None:
    """From step ``since`` on: the share of head-joint and corner contact-steps open, and the
    largest overlap of an open contact against ntdda's re-closing band."""
    share, deepest = {}, {}
    for k in ("head", "corner"):
        opened = total = 0
        worst = 0.0
        for s, step in trace.steps.items():
            if s < since:
                continue
            m = classes(step, start)[k]
            total += int(m.sum())
            opened += int((m & ~step["closed"]).sum())
            worst = max(worst, float(-step["dn"][m & ~step["closed"]].min(initial=0.0)))
        share[k], deepest[k] = opened / max(total, 1), worst
    print(f"{name}, steps {since}-{STEPS}: head-joint contact-steps open {share['head']:.1%}, corners open "
          f"{share['corner']:.1%}; deepest open overlap {1e6 * deepest['head']:.0f} µm (head), "
          f"{1e6 * deepest['corner']:.0f} µm (corner); ntdda's re-closing band 2e-4·w0 = {1e6 * band:.0f} µm")


def distances(name: str, trace: Trace, reference: Trace) -> None:
    """Largest distance of a free block's centroid from the reference run's, at chosen steps."""
    n = min(len(trace.centroid), len(reference.centroid))
    gap = np.linalg.norm(trace.centroid[:n, 1:] - reference.centroid[:n, 1:], axis=2).max(1)
    marks = [s for s in (10, 50, 80, 90, 100, 150, 200, 500, 1000, 2000) if s < n]
    print(f"{name}: largest centroid distance from ntdda [mm] at steps " +
          ", ".join(f"{s}: {1e3 * gap[s]:.3f}" for s in marks))


def trace_part(driver: str, geo: Path, ana: Path, work: Path) -> None:
    log = work / "contacts.log"
    info = ntdda_run(driver, geo, ana, log)
    nt = read_contact_log(log, np.array(info["centroids"]))
    case = dd.read_ntdda(geo, ana)
    band = 2e-4 * info["w0"]
    start = nt.centroid[0]
    print(f"ntdda: {info['blocks']} blocks, Δt {info['dt']} s, penalty {info['penalty']:g} N/m, w0 {info['w0']:.4f} m, "
          f"open–close iterations a step {info['oc_per_step']:.4f}")
    state_table("ntdda", nt, start)
    ntdda_openings(nt, start)
    open_overlaps("ntdda", nt, start, band)
    for name, rules in (("ddatai (its rules)", ""), ("ddatai, no impact rule", "noimpact"),
                        ("ddatai with ntdda's four rules", NTDDA_RULES)):
        t = time.process_time()
        tr = ddatai_trace(case, rules)
        state_table(f"{name} (CPU {time.process_time() - t:.1f} s)", tr, start)
        open_overlaps(name, tr, start, band)
        distances(name, tr, nt)


def extra_part(geo: Path, ana: Path) -> None:
    case = dd.read_ntdda(geo, ana)
    oc_changes.STEPS = STEPS
    for rules in ("", "noimpact"):
        res, log = oc_changes.run(case, frozenset(r for r in rules.split(",") if r), record=True)
        start = np.asarray(res.centroid[0])
        kinds: dict = {}
        for r in log:
            if not r["changed"]:
                continue
            rows = r["rows"]
            step = dict(a=np.array([c[0] for c in rows]), b=np.array([c[1] for c in rows]),
                        vv=np.array([c[2] for c in rows]))
            name = "+".join(k for k, m in classes(step, start).items() if m.any())
            name += " (impact retake)" if r["attempt"] > 1 else ""
            kinds[name] = kinds.get(name, 0) + 1
        n = len(res.steps)
        print(f"\nddatai, rules {rules or 'its own'}: solves a step {res.steps['oc_total'].mean():.4f}; solves that "
              "changed states, by the classes that changed:")
        for name, count in sorted(kinds.items(), key=lambda kv: -kv[1]):
            print(f"  {name:32s} {count:5d} ({count / n:.4f} a step)")


def closings_part(driver: str, sizes, work: Path) -> None:
    for n in sizes:
        geo, ana = grid_files(n, work, STEPS)
        log = work / f"contacts{n}.log"
        info = ntdda_run(driver, geo, ana, log)
        d = np.array([line.split() for line in open(log) if not line.startswith("C")], float)
        log.unlink()
        step, solve, prev, cur, dn = d[:, 0], d[:, 1], d[:, 6], d[:, 7], d[:, 9]
        close, opened = (prev == 0) & (cur > 0), (prev > 0) & (cur == 0)
        first = f"first at step {int(step[close].min())}, median overlap {-1e6 * np.median(dn[close]):.0f} µm" \
            if close.any() else "none"
        print(f"ntdda, {n} blocks: OC/step {info['oc_per_step']:.4f}; band 2e-4·w0 = {2e-4 * info['w0'] * 1e6:.0f} µm; "
              f"open → closed {int(close.sum())} ({first}); closed → open {int(opened.sum())}; steps with more "
              f"than one solve {len(np.unique(step[solve > 1]))}")


def beta_part(geo: Path, ana: Path) -> None:
    case = dd.read_ntdda(geo, ana)
    for rules in ("", "noimpact"):
        for beta in (0.5625, 0.5):
            tr = ddatai_trace(case, rules, newmark_beta=beta)
            print(f"ddatai, rules {rules or 'its own':9s} β = {beta}: solves a step {tr.solves.mean():.4f}")


PERTURB = [("<Youngsmod>1.0e8", f"<Youngsmod>{v:.3e}") for v in 1e8 * np.linspace(0.95, 1.05, 11)] + \
          [("<Friction>30.0", f"<Friction>{v:.2f}") for v in np.linspace(29.5, 30.5, 11)]
DDATAI_PERTURB = ("<Youngsmod>9.500e+07", "<Youngsmod>9.900e+07", "<Youngsmod>1.000e+08", "<Youngsmod>1.030e+08",
                  "<Friction>29.50", "<Friction>30.10")


def perturb_part(driver: str, geo: Path, ana: Path, work: Path, with_ddatai: bool) -> None:
    text = ana.read_text()
    print("\n| input | ntdda OC/step | ntdda largest sideways offset [mm] | ddatai solves/step | ddatai offset [mm] |")
    for old, new in PERTURB:
        if old not in text:
            raise RuntimeError(f"{old!r} not in {ana}")
        changed = work / ana.name
        changed.write_text(text.replace(old, new))
        info = ntdda_run(driver, geo, changed)
        c = np.array(info["centroids"])[1:]
        offset = float(np.max(np.abs(c[:, 0] - (np.floor(c[:, 0]) + 0.5))))  # blocks start at x = i + ½
        row = f"| {new} | {info['oc_per_step']:.4f} | {1e3 * offset:.2f} |"
        if with_ddatai and new in DDATAI_PERTURB:
            case = dd.read_ntdda(geo, changed)
            res = dd.simulate(case.scene, dataclasses.replace(case.params, kernels="numpy", initial_equilibrium=False),
                              steps=STEPS, record_every=STEPS)
            moved = np.asarray(res.centroid[-1]) - np.asarray(res.centroid[0])
            row += f" {res.steps['oc_total'].mean():.4f} | {1e3 * float(np.max(np.abs(moved[:, 0]))):.2f} |"
        else:
            row += " | |"
        print(row, flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--driver", required=True, help="the contact_log driver (benchmarks/ntdda_beside/build.sh)")
    ap.add_argument("--blocks", type=int, default=16)
    ap.add_argument("--parts", default="trace,extra,closings,beta,perturb")
    ap.add_argument("--sizes", default="4,16,64", help="grid sizes of the closings part")
    ap.add_argument("--ddatai-perturb", action="store_true")
    a = ap.parse_args()
    parts = a.parts.split(",")
    with tempfile.TemporaryDirectory(prefix="quiet16_") as tmp:
        work = Path(tmp)
        geo, ana = grid_files(a.blocks, work, STEPS)
        (work / "perturbed").mkdir()
        if "trace" in parts:
            trace_part(a.driver, geo, ana, work)
        if "extra" in parts:
            extra_part(geo, ana)
        if "closings" in parts:
            closings_part(a.driver, [int(n) for n in a.sizes.split(",")], work)
        if "beta" in parts:
            beta_part(geo, ana)
        if "perturb" in parts:
            perturb_part(a.driver, geo, ana, work / "perturbed", a.ddatai_perturb)


if __name__ == "__main__":
    main()
