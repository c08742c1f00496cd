"""How big the fused kernel's LLVM module is, whole and piece by piece.

    python benchmarks/fused_module.py [--cache DIR] [--pieces detect,open_close,...] [--keep DIR]
                                      [--calls N]

Taichi 1.7.4 keeps a kernel in its offline cache as LLVM IR (text, after its own optimisation);
a fresh process optimises that module again and makes machine code of it at its first launch
(benchmarks/results/fused_load.md), work that grows with the module. ``--cache``: a warm cache
of the whole ``run`` kernel; its largest file is the module (bytes, instructions). Each piece is
one phase of the step compiled alone in a kernel of ``run``'s signature, in a fresh process
(threads pinned) with a fresh cache of its own, started through `ddatai.fused.warm.warm` (the
piece ends the member, so the run stops): its module's bytes and instructions and the compile's
CPU seconds. The pieces overlap (``open_close`` holds ``factor_solve`` and ``law``); the whole
is more than their sum by the step's own body and the kernel's. ``--calls N``: instead, the
``N`` Taichi functions that build the most of ``run``'s Python-to-IR transform (no compile): how
often each is inlined, from where, and the AST nodes it builds (its own and with its callees;
a ``ti.static`` loop builds its body once a pass)."""

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


CALLS = r'''
import ast, collections, sys
sys.path.insert(0, {root!r})
import ddatai.fused.warm
from ddatai import backend
backend.ensure("cpu")
from taichi.lang import impl, kernel_impl
from taichi.lang.ast import ast_transformer_utils as atu
stack = ["<kernel run>"]
calls, own, total = collections.Counter(), collections.Counter(), collections.Counter()
callers = collections.defaultdict(collections.Counter)
func_call, build = kernel_impl.Func.__call__, atu.Builder.__call__
def counted_call(self, *args, **kwargs):
    name = self.func.__module__.rsplit(".", 1)[-1] + "." + self.func.__name__
    callers[name][stack[-1]] += 1
    calls[name] += 1
    stack.append(name)
    try:
        return func_call(self, *args, **kwargs)
    finally:
        stack.pop()
def counted_build(self, ctx, node):
    if isinstance(node, (ast.stmt, ast.expr)):
        own[stack[-1]] += 1
        for name in set(stack):
            total[name] += 1
    return build(self, ctx, node)
kernel_impl.Func.__call__ = counted_call
atu.Builder.__call__ = counted_build
class Transformed(Exception):
    pass
class Program:  # stop before the compile: the transform is what is counted
    def __init__(self, prog):
        self._prog = prog
    def __getattr__(self, name):
        return getattr(self._prog, name)
    def compile_kernel(self, *args):
        raise Transformed()
impl.get_runtime().prog = Program(impl.get_runtime().prog)
try:
    ddatai.fused.warm.warm()
except Exception as e:
    if "Transformed" not in repr(e) and not isinstance(e, Transformed):
        raise
print(f"{{sum(calls.values())}} inlined calls, {{total['<kernel run>']}} AST nodes built")
print("| Taichi function | inlined | AST nodes, own | with callees | called from |\n|---|---|---|---|---|")
for name, n in total.most_common({top}):
    print(f"| `{{name}}` | {{calls.get(name, 1)}} | {{own[name]}} | {{n}} | {{dict(callers[name].most_common(3))}} |")
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
    ap.add_argument("--calls", type=int, default=0, help="the N functions that build the most of the transform")
    a = ap.parse_args()
    if a.calls:
        with tempfile.TemporaryDirectory(prefix="fused_module_") as cache:
            subprocess.run([sys.executable, "-c", CALLS.format(root=str(ROOT), top=a.calls)], cwd=ROOT, check=True,
                           env={**os.environ, **PINNED, "TI_OFFLINE_CACHE_FILE_PATH": cache}, timeout=600)
        return
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
