"""A field mapper for the joint-set fitting tests: traces of one set (from `dd.joint_sets`)
recorded in a window along a scanline, as docs/method/joint_mapping.md asks a mapper to."""

import math

import numpy as np


def map_window(traces, *, origin, trend, length, window):
    """Rows (dict per trace) of a window survey: the scanline starts at ``origin`` and runs
    ``length`` m at ``trend`` degrees CCW from +x, in the middle of a window ``window`` m high.

    Every trace crossing the window whose line, extended, crosses the scanline within its
    length is recorded: apparent dip, where it crosses the scanline (None if it stops short),
    the length seen in the window, how many ends lie beyond it, and the rock bridge from its
    up-dip end to the next trace of its line when both are seen in the window."""
    o = np.asarray(origin, float)
    u = np.array([math.cos(math.radians(trend)), math.sin(math.radians(trend))])
    v = np.array([-u[1], u[0]])
    half = 0.5 * window
    segs = []
    for xy, _ in traces:
        p, q = np.asarray(xy[0], float), np.asarray(xy[-1], float)
        d = q - p
        if d[1] < 0 or (d[1] == 0 and d[0] < 0):
            p, q, d = q, p, -d
        segs.append((p, q, d / np.hypot(*d), float(np.hypot(*d))))
    # the traces of one line: same direction and offset (the generator's lines are straight)
    lines = {}
    for k, (p, q, d, ln) in enumerate(segs):
        key = (round(math.atan2(d[1], d[0]), 9), round(float(p @ np.array([-d[1], d[0]])), 6))
        lines.setdefault(key, []).append(k)
    nxt = {}
    for ks in lines.values():
        ks = sorted(ks, key=lambda k: float(segs[k][0] @ segs[k][2]))
        nxt.update({a: b for a, b in zip(ks, ks[1:])})
    rows = []
    for k, (p, q, d, ln) in enumerate(segs):
        vp, vd = float((p - o) @ v), float(d @ v)
        if abs(vd) < 1e-12:
            continue
        t_cross = -vp / vd                      # along the trace from p, to the scanline
        s = float((p + t_cross * d - o) @ u)    # where its line crosses the scanline
        if not 0.0 <= s <= length:
            continue
        lo, hi = sorted(((-half - vp) / vd, (half - vp) / vd))
        a, b = max(lo, 0.0), min(hi, ln)
        if b <= a:
            continue                            # outside the window
        censored = int(lo > 0.0) + int(hi < ln)
        gap = None
        if k in nxt:
            p2 = segs[nxt[k]][0]
            inside = lambda x: abs(float((x - o) @ v)) <= half  # noqa: E731
            if inside(q) and inside(p2):
                gap = float((p2 - q) @ d)
        rows.append({"dip": math.degrees(math.atan2(d[1], d[0])) % 180.0,
                     "position": s if 0.0 <= t_cross <= ln else None,
                     "length": b - a, "censored": censored, "gap": gap})
    return rows
