"""Sarma against DDA strength reduction over bilinear and stepped footwall slabs.

    TI_CPU_MAX_NUM_THREADS=1 OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 \\
        python benchmarks/sarma_dda_sweep.py [--out benchmarks/results/sarma_dda_sweep.jsonl] [--limit N]

For each footwall slab of the sweep (`CASES`: `scenes/footwall.py`'s bilinear case with the
upper plane, the bedding, dipping ψ = 40–60°; the lower plane J1 dipping β = 15–35°; the kink B
where J1 daylights 1 or 4 m above the floor; the cross joint J2 perpendicular to the bedding, or vertical — a
stepped slab, whose riser J2 stands on the tread J1 —; φ = 25–40°, c = 0–20 kPa) the group
{toe block, slab} judged by kgm's Sarma evaluator and by its DDA strength reduction
(``kgm.evaluate(..., "dda")``, the fused engine where its kernel is compiled), beside the
two-block closed form (docs/kgm/footwall.md F3–F7) and the rigid slide on J1 (F8). One JSON
line per case (appended as it is computed: a long sweep keeps what it has) and, at the end, the
summary of docs/kgm/footwall.md §9: the ratio Sarma/DDA per case, its largest value, the cases
above 1.05 and whether kgm's row flags each of them.

Pin the threads (above): the machine is shared, and the sweep is serial.
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import platform
import sys
import time
from pathlib import Path
from types import SimpleNamespace
from typing import Optional

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the repository root: scenes/
import kgm  # noqa: E402
from kgm.report import judged_by_dda  # noqa: E402
from scenes import footwall as fw  # noqa: E402

#: the flag's threshold: Sarma above this times DDA's factor is reported (kgm.report.SARMA_ABOVE_DDA)
RATIO = 1.05


def cases() -> list[dict]:
    """The sweep: every ψ, β, kink and J2 of the grid with two of the four (φ, c) corners each,
    alternating, so that every corner meets every geometry factor (a half fraction)."""
    out = []
    corners = [(25.0, 0.0), (40.0, 20e3), (25.0, 20e3), (40.0, 0.0)]
    grid = itertools.product((40.0, 50.0, 60.0), (15.0, 25.0, 35.0), (1.0, 4.0), (None, 90.0))
    for i, (dip, toe_dip, kink, cross_dip) in enumerate(grid):
        foot = kink_foot(dip, toe_dip, kink)
        for friction, cohesion in (corners[0:2] if i % 2 == 0 else corners[2:4]):
            opts = dict(dip=dip, toe_dip=toe_dip, toe_foot=round(foot, 6), cross_foot=round(foot + 3.0, 6),
                        cross_dip=cross_dip, friction=friction, cohesion=cohesion, height=20.0)
            try:
                fw.geometry("bilinear", **opts)
            except ValueError:
                continue
            out.append(opts)
    return out


def kink_foot(dip: float, toe_dip: float, toe_height: float, thickness: float = 2.0) -> float:
    """Where the kink B lies along the bedding [m from the floor] for J1 (dipping ``toe_dip``)
    to daylight in the face ``toe_height`` above the floor: B + a·d_P on the face, with
    a = t / sin(ψ − β), has the height s·sinψ − a·sinβ."""
    psi, beta = math.radians(dip), math.radians(toe_dip)
    return (toe_height + thickness * math.sin(beta) / math.sin(psi - beta)) / math.sin(psi)


def toe_height(c: dict) -> float:
    """Height of J1's daylight F above the floor [m] (the kink's position, `kink_foot`)."""
    return float(fw.geometry("bilinear", **c)["F"][1])


def closed_form(opts: dict) -> float:
    try:
        return fw.closed_form_fs("bilinear", **opts)
    except ValueError:
        return math.nan


def run_case(opts: dict, stored: Optional[dict] = None) -> dict:
    """One case: Sarma's evaluation and DDA's strength reduction of the pair, and the DDA row
    (`kgm.report.judged_by_dda`) with its flag. ``stored``: a row of an earlier run of this
    sweep whose DDA factor is taken instead of running DDA again (the DDA judge is the same:
    only the Sarma side and the row are recomputed; the row says ``dda_reused``)."""
    scene, params = fw.build("bilinear", **opts)
    group = sorted({fw.P, fw.A})
    t0 = time.perf_counter()
    sarma = kgm.evaluate(scene, group, "sarma")
    t1 = time.perf_counter()
    if stored is None:
        dda = kgm.evaluate(scene, group, "dda", params=params)
        runs = len(dda.dda.runs)
    else:
        done = SimpleNamespace(fs=stored["dda"], critical_friction=math.nan,
                               judgement=SimpleNamespace(stable=stored["dda"] >= 1.0))
        dda, runs = judged_by_dda(sarma, done), stored["dda_runs"]
    t2 = time.perf_counter()
    return dict(case=opts, closed_form=closed_form(opts), rigid=fw.rigid_fs("bilinear", **opts),
                sarma=sarma.fs, sarma_mode=sarma.mode.kind.value,
                unbalanced=[r for r in sarma.rejected if "moment not balanced" in r], dda=dda.fs, dda_runs=runs,
                ratio=sarma.fs / dda.fs, flagged=getattr(dda, "sarma_above_dda", None) is not None,
                governing=dda.fs, dda_reused=stored is not None, sarma_s=t1 - t0,
                dda_s=stored["dda_s"] if stored else t2 - t1)


def summary(rows: list[dict]) -> str:
    ratios = [r["ratio"] for r in rows if math.isfinite(r["ratio"])]
    above = [r for r in rows if r["ratio"] > RATIO]
    worst = max(rows, key=lambda r: r["ratio"])
    lines = [f"cases: {len(rows)}; Sarma/DDA: min {min(ratios):.3f}, median {sorted(ratios)[len(ratios) // 2]:.3f}, "
             f"max {max(ratios):.3f} ({_name(worst['case'])}); above {RATIO}: {len(above)}, flagged: "
             f"{sum(r['flagged'] for r in above)}; translations taken out, their moments unbalanced: "
             f"{sum(bool(r.get('unbalanced')) for r in rows)}; turning governs: "
             f"{sum(r['sarma_mode'] == 'rotation' for r in rows)}"]
    lines.append("")
    lines.append("| ψ | β | toe m | J2 | φ | c kPa | closed form | rigid | Sarma | mode | out | DDA | Sarma/DDA | flag |")
    lines.append("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        c = r["case"]
        lines.append(f"| {c['dip']:g} | {c['toe_dip']:g} | {toe_height(c):.1f} | "
                     f"{'⊥ bedding' if c['cross_dip'] is None else 'vertical'} | {c['friction']:g} | "
                     f"{c['cohesion'] / 1e3:g} | {r['closed_form']:.4f} | {r['rigid']:.4f} | {r['sarma']:.4f} | "
                     f"{r['sarma_mode']} | {len(r.get('unbalanced') or []) or ''} | {r['dda']:.4f} | "
                     f"{r['ratio']:.3f} | {'yes' if r['flagged'] else ''} |")
    return "\n".join(lines)


def _name(c: dict) -> str:
    j2 = "J2 ⊥" if c["cross_dip"] is None else "J2 vertical"
    return (f"ψ {c['dip']:g}°, β {c['toe_dip']:g}°, toe {toe_height(c):.1f} m, {j2}, φ {c['friction']:g}°, "
            f"c {c['cohesion'] / 1e3:g} kPa")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="benchmarks/results/sarma_dda_sweep.jsonl")
    ap.add_argument("--limit", type=int, default=None, help="only the first N cases")
    ap.add_argument("--summary", action="store_true", help="print the summary of --out and stop")
    ap.add_argument("--dda-from", metavar="JSONL", help="take the DDA factors of the cases an earlier run of "
                    "this sweep stored there (Sarma and the flag recomputed)")
    args = ap.parse_args()
    out = Path(args.out)
    if not args.summary:
        done = [json.loads(x) for x in out.read_text().splitlines()] if out.exists() else []
        seen = [r["case"] for r in done]
        print(f"machine: {platform.processor() or platform.machine()}, Python {platform.python_version()}", flush=True)
        earlier = ([json.loads(x) for x in Path(args.dda_from).read_text().splitlines()] if args.dda_from else [])
        for opts in cases()[:args.limit]:
            if opts in seen:
                continue
            r = run_case(opts, next((e for e in earlier if e["case"] == opts), None))
            with out.open("a") as fh:
                fh.write(json.dumps(r) + "\n")
            print(f"{_name(opts)}: closed {r['closed_form']:.4f} Sarma {r['sarma']:.4f} ({r['sarma_mode']}) "
                  f"DDA {r['dda']:.4f} ratio {r['ratio']:.3f} ({r['dda_s']:.1f} s)", flush=True)
    rows = [json.loads(x) for x in out.read_text().splitlines()]
    print(summary(rows))


if __name__ == "__main__":
    main()
