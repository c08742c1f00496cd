"""ntdda's segment tests, shared by the block cutting (`ddatai.io.ntdda.geometry`) and what
follows it (`ddatai.io.ntdda.placement`): the domain scale w0 that every cutting tolerance is
relative to (dc02), and the segment intersection test (lns). NumPy only.
"""

from __future__ import annotations

import numpy as np

#: Parameter tolerance of ntdda's segment intersection test (lns): t in [-1e-7, 1 + 1e-7].
PARAMETER_TOL = 1e-7
#: Parallel-line test of lns, relative to w0² (|d0| < 1e-9·w0²).
_PARALLEL_TOL = 1e-9


def domain_scale(segments: np.ndarray) -> float:
    """ntdda's w0 (dc02): 1.02·max(H/2, W/2/1.3) over the segment end points [length].

    The 1.3 aspect factor and the 1.02 margin are ntdda's; w0 scales every cutting tolerance.
    """
    seg = np.asarray(segments, dtype=float).reshape(-1, 4)
    x = np.concatenate([seg[:, 0], seg[:, 2]])
    y = np.concatenate([seg[:, 1], seg[:, 3]])
    half_w = (x.max() - x.min()) / 2.0
    half_h = (y.max() - y.min()) / 2.0
    w0 = half_h if half_w <= 1.3 * half_h else half_w / 1.3
    return 1.02 * w0


def segment_intersection(w0: float, p1, p2, p3, p4, *, collinear: bool = True
                         ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """ntdda's segment intersection test (lns), vectorised over broadcast end points.

    Segment i runs p1 -> p2, segment j runs p3 -> p4. Returns ``(hit, t1, t2)``: whether they
    meet, and the parameters along i and j. Parameters within 1e-7 outside [0, 1] still count
    (touching end points meet). Parallel segments meet only when collinear and exactly one end
    point of j lies on i (end-to-end contact); collinear overlaps do not meet. With
    ``collinear=False`` parallel segments never meet (ntdda's edge-crossing test in dc06).
    """
    p1, p2, p3, p4 = (np.asarray(p, dtype=float) for p in (p1, p2, p3, p4))
    x21, y21 = p2[..., 0] - p1[..., 0], p2[..., 1] - p1[..., 1]
    x34, y34 = p3[..., 0] - p4[..., 0], p3[..., 1] - p4[..., 1]
    x31, y31 = p3[..., 0] - p1[..., 0], p3[..., 1] - p1[..., 1]
    x41, y41 = p4[..., 0] - p1[..., 0], p4[..., 1] - p1[..., 1]
    d0 = x21 * y34 - x34 * y21
    d1 = x31 * y34 - x34 * y31
    d2 = x21 * y31 - x31 * y21
    eps = _PARALLEL_TOL * w0 * w0
    lo, hi = -PARAMETER_TOL, 1.0 + PARAMETER_TOL
    normal = np.abs(d0) >= eps
    with np.errstate(divide="ignore", invalid="ignore"):
        t1n = np.where(normal, d1 / np.where(normal, d0, 1.0), 0.0)
        t2n = np.where(normal, d2 / np.where(normal, d0, 1.0), 0.0)
        hit_n = normal & (t1n >= lo) & (t1n <= hi) & (t2n >= lo) & (t2n <= hi)
        # collinear: parameters of p3 and p4 along i, from the larger coordinate of i's direction
        colinear = ~normal & (np.abs(d1) < eps)
        use_x = np.abs(x21) > np.abs(y21)
        a1 = np.where(use_x, x21, y21)
        a1 = np.where(a1 == 0.0, np.nan, a1)
        s3 = np.where(use_x, x31, y31) / a1
        s4 = np.where(use_x, x41, y41) / a1
    in3 = (s3 >= lo) & (s3 <= hi)
    in4 = (s4 >= lo) & (s4 <= hi)
    hit_c = colinear & (in3 ^ in4) & collinear
    hit = hit_n | hit_c
    t1 = np.where(hit_n, t1n, np.where(in3, s3, s4))
    t2 = np.where(hit_n, t2n, np.where(in3, 0.0, 1.0))
    return hit, np.where(hit, t1, 0.0), np.where(hit, t2, 0.0)
