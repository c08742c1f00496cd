"""The equilibrium stage's K and F assembled in full at every iterate against re-assembled only
where contacts opened or closed (`ddatai.reassembly`), in one process on the same model:

    python benchmarks/stage_assembly.py [--family slope] [--size 1600] [--pairs 2]

The two ways give the same K and F float for float (tests/test_reassembly.py), so the stage
takes the same path either way: the pair measures the assembly alone, without the noise of two
processes on a shared machine (a fresh-process pair, `benchmarks/scaling.py --baseline`, moves
±10–25 % in CPU on this machine). A first stage loads the kernels; then "full" and "partial"
alternate ``--pairs`` times. Prints the stage's CPU seconds, the CPU seconds of its assembly
(`ContactSystem.system`) and per iterate, and checks that the stage ended at the same vertices.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from scaling_scenes import case_parser, case_scene, use_checkout


def main() -> None:
    ap = case_parser(__doc__, size=1600)
    ap.add_argument("--pairs", type=int, default=2)
    a = ap.parse_args()
    use_checkout()
    import ddatai as dd
    from ddatai import reassembly
    from ddatai.start import settle
    from ddatai.step import Stepper

    model = dd.build_model(*case_scene(a))
    partial = reassembly.ContactSystem.system
    spent = {"full": [0.0, 0], "partial": [0.0, 0]}

    def timed(way):
        def system(self, contacts, sca):
            t = time.process_time()
            out = self._assemble_all(contacts, sca) if way == "full" else partial(self, contacts, sca)
            spent[way][0] += time.process_time() - t
            spent[way][1] += 1
            return out
        return system

    settle(Stepper(model), model.initial_state())  # the kernels loaded
    rows, ends = [], {}
    for _ in range(a.pairs):
        for way in ("full", "partial"):
            reassembly.ContactSystem.system = timed(way)
            before = list(spent[way])
            t = time.process_time()
            state, record = settle(Stepper(model), model.initial_state())
            cpu = time.process_time() - t
            ends.setdefault(way, state.vertex_xy)
            rows.append((way, cpu, spent[way][0] - before[0], spent[way][1] - before[1], record.solves,
                         record.held, record.released))
    reassembly.ContactSystem.system = partial
    print(f"{a.family} {model.n_free} free blocks, one process, CPU seconds")
    print("| way | stage CPU s | assembly CPU s | iterates | ms an iterate | solves | held | released |")
    print("|---|---|---|---|---|---|---|---|")
    for way, cpu, asm, n, solves, held, released in rows:
        print(f"| {way} | {cpu:.2f} | {asm:.3f} | {n} | {asm / max(n, 1) * 1e3:.2f} | {solves} | {held} | {released} |")
    same = np.array_equal(ends["full"], ends["partial"])
    print(f"the same vertices at the stage's end: {same}")
    sys.exit(0 if same else 1)


if __name__ == "__main__":
    main()
