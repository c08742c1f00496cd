"""How big the fused kernel's LLVM module is, whole and piece by piece.

    python benchmarks/fused_module.py [--cache DIR] [--pieces detect,open_close,...] [--keep DIR]

Taichi 1.7.4 keeps a kernel in its offline cache as LLVM IR (text, after its own optimisation);
a fresh process optimises that module again and makes machine code of it at its first launch
(benchmarks/results/fused_load.md), work that grows with the module. ``--cache``: a warm cache
of the whole ``run`` kernel; its largest file is the module (bytes, instructions). Each piece is
one phase of the step compiled alone in a kernel of ``run``'s signature, in a fresh process
(threads pinned) with a fresh cache of its own, started through `ddatai.fused.warm.warm` (the
piece ends the member, so the run stops): its module's bytes and instructions and the compile's
CPU seconds. The pieces overlap (``open_close`` holds ``factor_solve`` and ``law``); the whole
is more than their sum by the step's own body and the kernel's."""

import argparse
import os
import resource
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PINNED = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "TI_CPU_MAX_NUM_THREADS": "1"}

#: piece -> the body of the probe kernel's member loop (``dt``, ``beta`` defined; any result goes
#: to the member's row so that nothing is dropped as dead code)
PIECES = {
    "detect": "E.mi[m, 0] = contacts.detect(E, m)",
    "open_close": "a, b, c, d = iterate.open_close(E, m, dt, beta, E.mi[m, 1] > 0)\nE.mf[m, 0] = a + b + c + d",
    "factor_solve": "if system.factor(E, m, E.mi[m, 2] > 0):\n    E.mi[m, 0] = system.solve(E, m)",
    "law": ("E.mf[m, 0] = law.evaluate(E, m, 3, 0) + law.violations(E, m, 0)\nlaw.internal_force(E, m, 1, 5)\n"
            "a, b = law.judge(E, m, 0, 1)\nE.mf[m, 1] = a + b"),
    "impacts": ("E.mf[m, 0] = impacts.approach_bound(E, m, dt, beta)\nif impacts.impacted(E, m):\n"
                "    if impacts.impact_projection(E, m, dt, beta):\n        impacts.plastic_start(E, m)\n"
                "impacts.swap_start(E, m)"),
    "rest": ("E.mf[m, 0] = S.rule(E, m, 0)\ncontacts.start(E, m, E.mi[m, 3])\ncontacts.vectors(E, m)\n"
             "contacts.envelope(E, m)\na, b, c, d = S.accept(E, m)\nE.mf[m, 1] = a + b + c + d\n"
             "e, f = S.work(E, m)\nE.mf[m, 2] = e + f + S.update(E, m, dt, beta)\n"
             "k, g, s, cc = S.energies(E, m, 1, 2, 3)\nE.mf[m, 3] = k + g + s + cc\ncontacts.hand_over(E, m)"),
}

PROBE = '''
import sys
sys.path.insert(0, {root!r})
import taichi as ti
import ddatai.fused.kernel as K
from ddatai.fused.arrays import Pack
from ddatai.fused import contacts, impacts, iterate, law, system, step as S
from ddatai.fused.layout import DONE, MF_BETA, MF_DT, MI_STATUS


@ti.kernel
def probe(E: Pack, members: ti.i32):
    for m in range(members):
        dt = E.mf[m, MF_DT]
        beta = E.mf[m, MF_BETA]
{body}
        E.mi[m, MI_STATUS] = DONE


K.run = probe
import ddatai.fused.warm as W
try:
    W.warm()
except Exception as e:  # the piece's garbage results, after its compile (else no module: said below)
    print(type(e).__name__, str(e)[:300], file=sys.stderr)
'''


def module(path: Path) -> tuple:
    """(bytes, LLVM instructions) of a cached kernel file (its IR is text)."""
    data = path.read_bytes()
    text = data[data.find(b"; ModuleID"):].split(b"\x00")[0].decode("latin1")
    count, inside = 0, False
    for line in text.split("\n"):
        if line.startswith("define"):
            inside = True
        elif line.startswith("}"):
            inside = False
        elif inside and line.startswith("  "):
            count += 1
    return len(data), count


def largest(cache: str, err: str = "") -> Path:
    files = [Path(cache)] if Path(cache).is_file() else list(Path(cache).rglob("*.tic"))
    if not files:
        raise RuntimeError(f"no compiled kernel in {cache}: {err[-2000:]}")
    return max(files, key=lambda f: f.stat().st_size)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cache", default="", help="a warm offline cache of the whole run kernel (or its .tic file)")
    ap.add_argument("--pieces", default=",".join(PIECES))
    ap.add_argument("--keep", default="", help="keep each piece's cache in KEEP/<piece> (else a temporary one)")
    a = ap.parse_args()
    print(f"load {os.getloadavg()[0]:.1f} at the start; checkout {ROOT}")
    print("| module | bytes | LLVM instructions | compile CPU [s] |\n|---|---|---|---|")
    if a.cache:
        size, count = module(largest(a.cache))
        print(f"| the whole `run` kernel ({a.cache}) | {size:,} | {count:,} | |")
    for name in a.pieces.split(","):
        body = "\n".join(" " * 8 + line for line in PIECES[name].split("\n"))
        with tempfile.TemporaryDirectory(prefix="fused_module_") as tmp:
            cache = str(Path(a.keep) / name) if a.keep else tmp
            Path(cache).mkdir(parents=True, exist_ok=True)
            before = resource.getrusage(resource.RUSAGE_CHILDREN)
            script = Path(cache) / "probe.py"  # Taichi reads a kernel's source from its file
            script.write_text(PROBE.format(root=str(ROOT), body=body))
            proc = subprocess.run([sys.executable, str(script)], cwd=ROOT, check=True,
                           capture_output=True, text=True, env={**os.environ, **PINNED, "TI_OFFLINE_CACHE_FILE_PATH": cache},
                           timeout=1800)
            after = resource.getrusage(resource.RUSAGE_CHILDREN)
            cpu = after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime
            size, count = module(largest(cache, proc.stderr))
        print(f"| piece `{name}` | {size:,} | {count:,} | {cpu:.1f} |", flush=True)
    print(f"load {os.getloadavg()[0]:.1f} at the end")


if __name__ == "__main__":
    main()
