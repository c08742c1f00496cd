"""MKL PARDISO's own parameters measured on the project's real stiffness matrices.

    python benchmarks/pardiso_levers.py capture --family slope --size 391 [--steps 6]
    python benchmarks/pardiso_levers.py time --cases slope:391,slope:1537 [--variants base,mtype1]
                                             [--threads 1,2] [--repeat 5] [--kind lu|spd|both]
    python benchmarks/pardiso_levers.py paired --baseline <other checkout> --family slope --size 391
                                               [--steps 20] [--protocol settled|ntdda] [--repeat 3]

``capture`` runs a scaling scene (`benchmarks/scaling_scenes.py`, ntdda's protocol: from rest
under sudden gravity) for a few steps with the solver's factorisation hooked, and saves the
matrices PARDISO factorised after the first step — Cholesky (a symmetric K) and LU (friction
coupled to the normal force of the same solve, a non-symmetric K) — with their right-hand sides
to ``--cache`` (not the repository: 0.1–0.4 GB a case at 25,600 blocks).

``time`` factorises those matrices with each variant of PARDISO's parameters (`VARIANTS`) beside
today's (``base``: `ddatai.pardiso._Pardiso`), in one process, alternating the variants in
every repeat: one analysis per variant and matrix (phase 11, timed once), then ``--repeat``
numerical factorisations (phase 22 with the analysis kept, as a run refactorises) and solves
(phase 33), each timed in CPU and wall seconds, the factor freed (phase 0) after each. It
reports the medians, the ratio to ``base`` of each variant's factorisation (the median of the
per-repeat pairs), the factor's nonzeros (MKL's iparm(18)), its MFLOP (iparm(19)), perturbed
pivots (iparm(14)), peak memory (iparm(15)–(17)), the relative residual of the solve
|b − K x|max / |b|max and its difference from ``base``'s solution, and whether two
factorisations give the same solution to the bit (the conditional numerical reproducibility the
solver keeps). MKL's threads are set with ``mkl_set_num_threads`` and iparm(34) follows them.
Writes ``--out`` (a markdown table per thread count), and prints it.

``paired`` runs a scene end to end in fresh processes, the other checkout's code then this
one's, with every PARDISO call timed by matrix type and phase (``calls``): CPU of the stage and
the steps, PARDISO's and the LU's share, the factorisations, a hash of the final state.
"""

from __future__ import annotations

import argparse
import ctypes
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from scaling_scenes import ROOT, SCENES, use_checkout  # noqa: E402

CACHE = Path("/tmp/pardiso_levers")

#: variant name -> (kinds it applies to, mtype for (spd, lu) or None for today's, iparm overrides
#: (zero-based index: value)); "base" is today's `_Pardiso` parameters
VARIANTS = {
    "base": (("spd", "lu"), None, {}),
    # main's parameters before this measurement: the general LU (scaling, weighted matching) for
    # the coupled K
    "before": (("spd", "lu"), None, {}),
    "mtype11": (("lu",), 11, {10: 1, 12: 1}),
    # the coupled K as structurally symmetric: LU on the symmetric pattern, diagonal pivots
    # with perturbation, no scaling or weighted matching (today's "base" for the LU)
    "mtype1": (("lu",), 1, {10: 0, 12: 0}),
    # the general non-symmetric solver without scaling and matching (the half of mtype 1 that is
    # not the symmetric structure), and without scaling only
    "nomatch": (("lu",), 11, {10: 0, 12: 0}),
    "noscale": (("lu",), 11, {10: 0, 12: 1}),
    # MKL converts the CSR to variable-block rows (VBSR) itself: iparm(37) < 0
    "vbsr": (("spd", "lu"), None, {36: -80}),
    "mtype1_vbsr": (("lu",), 1, {10: 0, 12: 0, 36: -80}),
    # the 6x6 blocks given as BSR: iparm(37) = 6 (the matrix passed in block form)
    "bsr6": (("spd", "lu"), None, {36: 6}),
    "mtype1_bsr6": (("lu",), 1, {10: 0, 12: 0, 36: 6}),
    # ordering: parallel METIS (gives up CNR, MKL's documentation), and METIS with the
    # "aggressiveness" L of iparm(2) = 10 L + K of MKL 2025+
    "pmetis": (("spd", "lu"), None, {1: 3, 33: 0}),
    "metis_L5": (("spd", "lu"), None, {1: 52}),
    "metis_L10": (("spd", "lu"), None, {1: 102}),
    "mindeg": (("spd", "lu"), None, {1: 0}),
    # two-level factorisation; improved two-level (non-symmetric only)
    "twolevel": (("spd", "lu"), None, {23: 1}),
    "twolevel10": (("lu",), 11, {10: 1, 12: 1, 23: 10}),
    "mtype1_twolevel": (("lu",), 1, {10: 0, 12: 0, 23: 1}),
    # without conditional numerical reproducibility (what it costs; not a candidate)
    "nocnr": (("spd", "lu"), None, {33: 0}),
    # forward/backward solve: parallel (1), and (2)
    "solve1": (("spd", "lu"), None, {24: 1}),
    "solve2": (("spd", "lu"), None, {24: 2}),
}


def _hook_capture(keep: int, skip_steps: int, store: dict, stepper_ref: list):
    """Wrap `SparseSolver._factorise` to copy what PARDISO factorises (after ``skip_steps`` steps)."""
    from ddatai import solver as solver_mod

    original = solver_mod.SparseSolver._factorise

    def _factorise(self, data, indices, indptr, rhs, n, symmetric, *rest):
        step = stepper_ref[0]
        kind = "spd" if symmetric else "lu"
        # Cholesky factorisations are rare after the first step of a failing slope (none in
        # steps 2-8 of the 391-block slope): they are taken from any step
        if (step >= skip_steps or symmetric) and len(store[kind]) < keep:
            store[kind].append(dict(data=np.array(data), indices=np.array(indices, dtype=np.int32),
                                    indptr=np.array(indptr, dtype=np.int32), rhs=np.array(rhs), step=step))
        return original(self, data, indices, indptr, rhs, n, symmetric, *rest)

    solver_mod.SparseSolver._factorise = _factorise


def capture(a) -> None:
    use_checkout()
    import dataclasses

    import ddatai as dd
    from ddatai.step import Stepper

    store = {"spd": [], "lu": []}
    step_ref = [0]
    _hook_capture(a.keep, a.skip, store, step_ref)
    scene, params = SCENES[a.family](a.size)
    params = dataclasses.replace(params, solver="pardiso")
    model = dd.build_model(scene, params)
    stepper = Stepper(model)
    state = model.initial_state()
    t = time.perf_counter()
    for k in range(a.steps):
        step_ref[0] = k
        state, rec = stepper.step(state)
        print(f"step {k}: {rec.oc_total if hasattr(rec, 'oc_total') else '?'} solves, "
              f"{time.perf_counter() - t:.1f} s; captured spd {len(store['spd'])} lu {len(store['lu'])}", flush=True)
        if all(len(v) >= a.keep for v in store.values()):
            break
    a.cache.mkdir(parents=True, exist_ok=True)
    for kind, mats in store.items():
        for i, m in enumerate(mats):
            path = a.cache / f"{a.family}{a.size}_{kind}{i}.npz"
            np.savez(path, **m)
            print(f"saved {path} (n {len(m['indptr']) - 1}, nnz {len(m['data'])}, step {m['step']})")


# ---------------------------------------------------------------------------------------- timing


def _mkl():
    use_checkout()
    from ddatai.pardiso import _mkl_runtime

    return _mkl_runtime()


class Variant:
    """A PARDISO handle with today's parameters (`ddatai.pardiso._Pardiso`) and a variant's
    overrides, on one captured matrix (its CSR as the variant's mtype reads it)."""

    def __init__(self, name: str, kind: str, m: dict, threads: int):
        from ddatai.pardiso import _Pardiso
        from ddatai.solver import _upper_triangle

        _, mtype, over = VARIANTS[name]
        if name == "before" and kind == "lu":
            mtype, over = VARIANTS["mtype11"][1:]
        # today's handle of each kind (`SparseSolver`): Cholesky, LU on the symmetric pattern
        self.h = _Pardiso(2 if kind == "spd" else 1)
        if mtype is not None:
            self.h.mtype = mtype
        self.h.iparm[33] = threads  # conditional numerical reproducibility for this many threads
        for i, v in over.items():
            self.h.iparm[i] = v
        self.h.iparm[17] = -1  # report the factor's nonzeros
        self.h.iparm[18] = -1  # report the factorisation's MFLOP
        n = len(m["indptr"]) - 1
        self.n = n
        self.kind = kind
        if self.h.mtype == 2:
            _, pos, ptr, idx = _upper_triangle(m["indptr"], m["indices"], n)
            data, ptr, idx = m["data"][pos], ptr, idx
        else:
            data, ptr, idx = m["data"], m["indptr"], m["indices"]
        self.bsr = int(self.h.iparm[36]) > 0
        if self.bsr:
            data, ptr, idx = _to_bsr(data, ptr, idx, n, int(self.h.iparm[36]), upper=self.h.mtype == 2)
        self.a = (np.ascontiguousarray(data, np.float64), np.ascontiguousarray(ptr, np.int32),
                  np.ascontiguousarray(idx, np.int32))
        self.b = np.ascontiguousarray(m["rhs"], np.float64)
        self.stats = {}

    def call_n(self, phase: int):
        """PARDISO's ``phase`` on this variant's matrix (`_Pardiso.call`; with a block format the
        order it passes, ``len(indptr) - 1``, is the number of block rows, as MKL asks)."""
        data, ptr, idx = self.a
        return self.h.call(phase, data, ptr, idx, self.b)

    def free(self) -> None:
        try:
            self.call_n(-1)
        except Exception:  # noqa: BLE001
            pass


def _to_bsr(data, ptr, idx, n, bs, upper):
    """CSR (full, or the upper triangle for mtype 2) as BSR with bs x bs blocks (block rows, block
    columns, each block's values row by row: MKL's BSR with iparm(37) = bs, zero-based)."""
    from scipy.sparse import csr_matrix

    k = csr_matrix((data, idx, ptr), shape=(n, n)).tobsr(blocksize=(bs, bs))
    k.sort_indices()
    if upper:  # keep the blocks on and above the diagonal
        rows = np.repeat(np.arange(k.shape[0] // bs), np.diff(k.indptr))
        keep = k.indices >= rows
        counts = np.bincount(rows[keep], minlength=k.shape[0] // bs)
        return (k.data[keep].reshape(-1), np.concatenate([[0], np.cumsum(counts)]), k.indices[keep])
    return k.data.reshape(-1), k.indptr, k.indices


def _csr(m):
    from scipy.sparse import csr_matrix

    n = len(m["indptr"]) - 1
    return csr_matrix((m["data"], m["indices"], m["indptr"]), shape=(n, n))


def time_case(path: Path, names: list, threads: int, repeat: int) -> list:
    """Rows of the table for one captured matrix and one thread count."""
    mkl = _mkl()
    mkl.MKL_Set_Num_Threads(ctypes.c_int(threads))
    m = dict(np.load(path))
    kind = "spd" if "_spd" in path.name else "lu"
    names = [v for v in names if kind in VARIANTS[v][0]]
    k = _csr(m)
    scale = float(np.abs(m["rhs"]).max())
    var, rows = {}, {}
    for name in names:
        try:
            v = Variant(name, kind, m, threads)
            c, w = time.process_time(), time.perf_counter()
            v.call_n(11)
            rows[name] = dict(variant=name, analysis_cpu=time.process_time() - c,
                              analysis_wall=time.perf_counter() - w, fact_cpu=[], fact_wall=[], solve_cpu=[],
                              solve_wall=[], same_bits=True, error="")
            var[name] = v
        except Exception as e:  # noqa: BLE001 - a variant MKL refuses is a row that says so
            rows[name] = dict(variant=name, error=str(e))
    for r in range(1, repeat):  # the analysis again, alternating (a new pattern's cost: phase 11)
        for name in (names if r % 2 else names[::-1]):
            if name in var:
                var[name].free()
                c = time.process_time()
                var[name].call_n(11)
                rows[name].setdefault("analyses_cpu", [rows[name]["analysis_cpu"]]).append(time.process_time() - c)
    for name in var:
        if "analyses_cpu" in rows[name]:
            rows[name]["analysis_cpu"] = statistics.median(rows[name].pop("analyses_cpu"))
    x_base = None
    for r in range(repeat):
        for name in (names if r % 2 == 0 else names[::-1]):
            if name not in var:
                continue
            v, row = var[name], rows[name]
            try:
                c, w = time.process_time(), time.perf_counter()
                v.call_n(22)
                row["fact_cpu"].append(time.process_time() - c)
                row["fact_wall"].append(time.perf_counter() - w)
                c, w = time.process_time(), time.perf_counter()
                x = v.call_n(33)
                row["solve_cpu"].append(time.process_time() - c)
                row["solve_wall"].append(time.perf_counter() - w)
            except Exception as e:  # noqa: BLE001
                row["error"] = str(e)
                del var[name]
                continue
            if r == 0:
                row["nnz_factor"] = int(v.h.iparm[17])
                row["mflop"] = int(v.h.iparm[18])
                row["perturbed"] = int(v.h.iparm[13])
                row["mem_mb"] = max(int(v.h.iparm[14]), int(v.h.iparm[15]) + int(v.h.iparm[16])) / 1024
                row["residual"] = float(np.abs(m["rhs"] - k @ x).max()) / scale
                row["x"] = x
                if name == "base":
                    x_base = x
            elif not np.array_equal(x, row["x"]):
                row["same_bits"] = False
            v.call_n(0)  # free the factor, keep the analysis (as the solver's release_factor)
    out = []
    for name in names:
        row = rows[name]
        if "x" in row:
            row["vs_base"] = (float(np.abs(row["x"] - x_base).max() / max(np.abs(x_base).max(), 1e-300))
                              if x_base is not None else float("nan"))
            del row["x"]
        if name in var:
            var[name].free()
        out.append(row)
    base = rows.get("base", {})
    for row in out:
        if row.get("fact_cpu") and base.get("fact_cpu"):
            row["ratio_cpu"] = statistics.median(a / b for a, b in zip(row["fact_cpu"], base["fact_cpu"]))
            row["ratio_wall"] = statistics.median(a / b for a, b in zip(row["fact_wall"], base["fact_wall"]))
    for row in out:
        row.update(case=path.stem, n=len(m["indptr"]) - 1, nnz=len(m["data"]), threads=threads)
    return out


def table(rows: list) -> str:
    head = ("| matrix | n | thr | variant | analysis CPU ms | fact. CPU ms | fact. wall ms | A/B CPU | A/B wall | "
            "solve CPU ms | factor nnz | MFLOP | MB | perturbed | residual | vs base | bit-same |")
    lines = [head, "|" + "---|" * (head.count("|") - 1)]
    for r in rows:
        if r.get("error") and not r.get("fact_cpu"):
            lines.append(f"| {r['case']} | {r['n']:,} | {r['threads']} | {r['variant']} | refused: {r['error']} |"
                         + " |" * 12)
            continue
        med = lambda key: statistics.median(r[key]) * 1e3  # noqa: E731
        lines.append(
            f"| {r['case']} | {r['n']:,} | {r['threads']} | {r['variant']} | {r['analysis_cpu'] * 1e3:.1f} | "
            f"{med('fact_cpu'):.1f} | {med('fact_wall'):.1f} | {r.get('ratio_cpu', float('nan')):.2f} | "
            f"{r.get('ratio_wall', float('nan')):.2f} | {med('solve_cpu'):.2f} | {r['nnz_factor']:,} | "
            f"{r['mflop']:,} | {r['mem_mb']:.0f} | {r['perturbed']} | {r['residual']:.1e} | {r['vs_base']:.1e} | "
            f"{'yes' if r['same_bits'] else 'NO'} |")
    return "\n".join(lines)


def time_all(a) -> None:
    names = a.variants.split(",")
    if "base" not in names:
        names = ["base"] + names
    paths = []
    for case in a.cases.split(","):
        for kind in (("spd", "lu") if a.kind == "both" else (a.kind,)):
            paths += sorted(a.cache.glob(f"{case.replace(':', '')}_{kind}{a.index}.npz"))
    rows = []
    for threads in (int(t) for t in a.threads.split(",")):
        for path in paths:
            if a.fresh:  # each matrix in its own process (the thread count is fixed at MKL's first call)
                cmd = [sys.executable, __file__, "time1", str(path), ",".join(names), str(threads), str(a.repeat)]
                proc = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
                if proc.returncode:
                    print(proc.stderr[-2000:], file=sys.stderr)
                    continue
                got = json.loads(proc.stdout.strip().splitlines()[-1])
            else:
                got = time_case(path, names, threads, a.repeat)
            rows += got
            print(table(got), flush=True)
    text = table(rows)
    if a.out:
        a.out.parent.mkdir(parents=True, exist_ok=True)
        a.out.write_text(text + "\n")
        (a.out.with_suffix(".json")).write_text(json.dumps(rows, indent=1))
    print(text)


def calls(a) -> None:
    """One run of a scene in this process (``import ddatai`` from ``PYTHONPATH``: this checkout or
    ``--baseline``'s) with every PARDISO call timed by (matrix type, phase): prints a JSON line
    with the run's CPU seconds (stage and steps), PARDISO's by type and phase, and a hash of the
    final vertices and velocities."""
    import dataclasses
    import hashlib

    import ddatai as dd
    from ddatai import pardiso as pm
    from ddatai.step import Stepper

    spent: dict = {}
    original = pm._Pardiso.call

    def call(self, phase, *args):
        c = time.process_time()
        try:
            return original(self, phase, *args)
        finally:
            key = f"{self.mtype}/{phase}"
            got = spent.setdefault(key, [0, 0.0])
            got[0] += 1
            got[1] += time.process_time() - c

    pm._Pardiso.call = call
    scene, params = SCENES[a.family](a.size)
    model = dd.build_model(scene, dataclasses.replace(params, solver="pardiso"))
    stepper = Stepper(model)
    state = model.initial_state()
    cpu = time.process_time()
    if a.protocol == "settled":
        from ddatai.start import settle

        state, _ = settle(stepper, state)
    stage = time.process_time() - cpu
    for _ in range(a.steps):
        state, _ = stepper.step(state)
    total = time.process_time() - cpu
    digest = hashlib.sha1(np.ascontiguousarray(state.vertex_xy).tobytes()
                          + np.ascontiguousarray(state.block_velocity).tobytes()).hexdigest()[:12]
    print(json.dumps(dict(stage_cpu=stage, steps_cpu=total - stage, pardiso=spent,
                          pardiso_cpu=sum(v[1] for v in spent.values()),
                          lu_cpu=sum(v[1] for k, v in spent.items() if k.split("/")[0] in ("1", "11")),
                          factorisations=stepper.solver.factorisations, state=digest)))


def paired_calls(a) -> None:
    """`calls` in fresh processes, ``--baseline``'s code then this checkout's, ``--repeat`` pairs."""
    rows = {"B": [], "A": []}
    for _ in range(a.repeat):
        for label, tree in (("B", a.baseline), ("A", ROOT)):
            cmd = [sys.executable, str(Path(__file__).resolve()), "calls", "--family", a.family, "--size", str(a.size),
                   "--steps", str(a.steps), "--protocol", a.protocol]
            proc = subprocess.run(cmd, capture_output=True, text=True, cwd=tree,
                                  env={**os.environ, "PYTHONPATH": str(tree)})
            if proc.returncode:
                print(proc.stderr[-2000:], file=sys.stderr)
                continue
            row = json.loads(proc.stdout.strip().splitlines()[-1])
            rows[label].append(row)
            print(label, json.dumps({k: v for k, v in row.items() if k != "pardiso"}), flush=True)
    lines = [f"| {a.family} {a.size} ({a.protocol}, {a.steps} steps) | B | A | A/B |", "|---|---|---|---|"]
    for key in ("stage_cpu", "steps_cpu", "pardiso_cpu", "lu_cpu", "factorisations"):
        b = [r[key] for r in rows["B"]]
        v = [r[key] for r in rows["A"]]
        ratio = statistics.median(x / y for x, y in zip(v, b) if y) if b and v else float("nan")
        lines.append(f"| {key} | {statistics.median(b):.2f} | {statistics.median(v):.2f} | {ratio:.2f} |")
    lines.append(f"| final state | {', '.join(sorted({r['state'] for r in rows['B']}))} | "
                 f"{', '.join(sorted({r['state'] for r in rows['A']}))} | |")
    print("\n".join(lines))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    c = sub.add_parser("capture")
    c.add_argument("--family", default="slope", choices=tuple(SCENES))
    c.add_argument("--size", type=int, default=391)
    c.add_argument("--steps", type=int, default=6)
    c.add_argument("--skip", type=int, default=1, help="steps before the LU capture (the first one's K is from rest)")
    c.add_argument("--keep", type=int, default=2, help="matrices kept of each kind")
    c.add_argument("--cache", type=Path, default=CACHE)
    t = sub.add_parser("time")
    t.add_argument("--cases", default="slope:391")
    t.add_argument("--variants", default=",".join(VARIANTS))
    t.add_argument("--threads", default="1")
    t.add_argument("--repeat", type=int, default=5)
    t.add_argument("--kind", default="both", choices=("both", "spd", "lu"))
    t.add_argument("--index", default="0", help="which captured matrix of each kind (glob digit)")
    t.add_argument("--fresh", action="store_true", help="each matrix in a fresh process")
    t.add_argument("--cache", type=Path, default=CACHE)
    t.add_argument("--out", type=Path, default=None)
    for name in ("calls", "paired"):
        r = sub.add_parser(name)
        r.add_argument("--family", default="slope", choices=tuple(SCENES))
        r.add_argument("--size", type=int, default=391)
        r.add_argument("--steps", type=int, default=10)
        r.add_argument("--protocol", default="settled", choices=("settled", "ntdda"))
        r.add_argument("--baseline", type=Path, default=None, help="paired: the other checkout (B)")
        r.add_argument("--repeat", type=int, default=3)
    o = sub.add_parser("time1")
    o.add_argument("path", type=Path)
    o.add_argument("names")
    o.add_argument("threads", type=int)
    o.add_argument("repeat", type=int)
    a = ap.parse_args()
    if a.cmd == "capture":
        capture(a)
    elif a.cmd == "time":
        time_all(a)
    elif a.cmd == "calls":
        calls(a)
    elif a.cmd == "paired":
        paired_calls(a)
    else:
        print(json.dumps(time_case(a.path, a.names.split(","), a.threads, a.repeat)))


if __name__ == "__main__":
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    main()
