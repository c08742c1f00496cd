"""Where the CPU of Example II's DDA-judged study goes, process by process and thread by thread.

    python benchmarks/study_processes.py [--root CHECKOUT] [--samples 400] [--workers 2] [--every 0.1]

Runs ``benchmarks/small_models.py``'s study (the one `benchmarks/study_ab.py` times: 2 worker
processes, the fused engine) in a fresh process with threads pinned (BLAS, OpenMP and Taichi one
thread each) and reads, every ``--every`` seconds, ``/proc/<pid>/task/<tid>/stat`` of that process
and of every process it starts: each thread's user + system CPU and whether it is running.
Prints, for each process (the study's own, each preparing worker, the runner that loads the
fused kernel — the one that maps Taichi's library —, Python's resource tracker): when it started
and ended, its CPU, the CPU of each of its threads, and a timeline of the CPU each process took in
each second. CPU that a thread burns while its process waits (a polling loop, a thread pool
spinning) shows as CPU in a thread or a second where the process does no work of its own.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from small_models import PINNED, STUDY  # noqa: E402

TICK = os.sysconf("SC_CLK_TCK")


def _stat(path: str):
    """(comm, state, ppid, utime + stime [s], start [ticks]) of a /proc stat file, or None."""
    try:
        with open(path) as fh:
            text = fh.read()
    except OSError:
        return None
    head, rest = text.split(" (", 1)
    comm, rest = rest.rsplit(") ", 1)
    f = rest.split()
    return comm, f[0], int(f[1]), (int(f[11]) + int(f[12])) / TICK, int(f[19])


def _children(pid: int) -> list[int]:
    out = []
    for tid in os.listdir(f"/proc/{pid}/task") if os.path.isdir(f"/proc/{pid}/task") else ():
        try:
            with open(f"/proc/{pid}/task/{tid}/children") as fh:
                out += [int(c) for c in fh.read().split()]
        except OSError:
            pass
    return out


def _maps_taichi(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/maps") as fh:
            return "taichi" in fh.read()
    except OSError:
        return False


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--root", default=str(HERE.parent))
    ap.add_argument("--samples", type=int, default=400)
    ap.add_argument("--every", type=float, default=0.1)
    ap.add_argument("--workers", type=int, default=2, help="the study's workers= (1: in its own process)")
    a = ap.parse_args()
    root = Path(a.root).resolve()
    out = f"/tmp/ddatai_study_processes_{os.getpid()}.npy"
    code = STUDY.format(root=str(root), script=f"{root}/scenes/example_2.py", kernels="fused", n=a.samples, out=out)
    code = code.replace("workers=2,", f"workers={a.workers},")
    load0 = os.getloadavg()[0]
    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            cwd=root, env={**os.environ, **PINNED})
    seen: dict = {}     # pid -> {first, last, cpu, threads: {tid: (comm, cpu)}, taichi, series: [(t, cpu)]}
    running: dict = {}  # pid -> samples in which a thread was running
    while proc.poll() is None:
        now = time.perf_counter() - t0
        pids, todo = [], [proc.pid]
        while todo:
            p = todo.pop()
            pids.append(p)
            todo += _children(p)
        for p in pids:
            rec = seen.setdefault(p, dict(first=now, last=now, cpu=0.0, threads={}, taichi=False, series=[]))
            try:
                tids = os.listdir(f"/proc/{p}/task")
            except OSError:
                continue
            total, busy = 0.0, 0
            for tid in tids:
                s = _stat(f"/proc/{p}/task/{tid}/stat")
                if s is None:
                    continue
                rec["threads"][tid] = (s[0], s[3])
                rec.setdefault("tseries", {}).setdefault(tid, []).append((now, s[3]))
                busy += s[1] == "R"
            total = sum(c for _, c in rec["threads"].values())
            rec["cpu"], rec["last"] = total, now
            rec["series"].append((now, total))
            running[p] = running.get(p, 0) + (busy > 0)
            if not rec["taichi"] and len(rec["series"]) % 5 == 1:
                rec["taichi"] = _maps_taichi(p)
        time.sleep(a.every)
    wall = time.perf_counter() - t0
    stdout, stderr = proc.communicate()
    if proc.returncode != 0:
        raise SystemExit(stderr[-3000:])
    study_wall, pf = stdout.strip().splitlines()[-1].split()
    print(f"# {a.samples} samples, root {root}; load {load0:.1f} -> {os.getloadavg()[0]:.1f}; "
          f"wall {wall:.1f} s (study {float(study_wall):.1f} s, {a.samples / float(study_wall):.1f} samples/s), "
          f"P_f {pf}")
    names = {}
    workers = 0
    for p, rec in seen.items():
        if p == proc.pid:
            names[p] = "study"
        elif rec["taichi"]:
            names[p] = "runner"
        elif len(rec["series"]) and rec["cpu"] < 0.5:
            names[p] = "tracker"
        else:
            workers += 1
            names[p] = f"worker{workers}"
    total = sum(r["cpu"] for r in seen.values())
    print(f"process tree CPU {total:.2f} s ({1e3 * total / a.samples:.1f} ms a sample)")
    for p, rec in seen.items():
        threads = sorted(rec["threads"].items(), key=lambda kv: -kv[1][1])
        desc = ", ".join(f"{c}:{cpu:.2f}" for _, (c, cpu) in threads[:6] if cpu > 0)
        print(f"{names[p]:8s} pid {p}: {rec['first']:5.1f}-{rec['last']:5.1f} s, CPU {rec['cpu']:6.2f} s, "
              f"{len(rec['threads'])} threads (running in {running.get(p, 0)} of {len(rec['series'])} reads); "
              f"threads' CPU {desc}")
    # CPU a second, per process, and per thread of the runner (those that took CPU)
    horizon = int(wall) + 1
    runner = [p for p in seen if names[p] == "runner"]
    busy_threads = []
    for p in runner:
        for tid, series in seen[p].get("tseries", {}).items():
            if series[-1][1] > 0.05:
                busy_threads.append((f"r.{tid}", series))
    columns = [(names[p], rec["series"]) for p, rec in seen.items()] + busy_threads
    print("second " + " ".join(f"{n:>8s}" for n, _ in columns))
    for sec in range(horizon):
        cells = []
        for _, series in columns:
            before = [c for t, c in series if t <= sec] or [0.0]
            upto = [c for t, c in series if t <= sec + 1] or [0.0]
            cells.append(f"{upto[-1] - before[-1]:8.2f}")
        print(f"{sec:6d} " + " ".join(cells))


if __name__ == "__main__":
    main()
