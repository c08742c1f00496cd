"""The broad phase: block bounding boxes binned into a hashed uniform grid (a counting sort
with a prefix sum), pairs found in the 3×3 neighbouring cells, and the boxes larger than a
cell tested against every box. ``ddatai.contacts.broad_phase`` calls them as one kernel,
`broad_pairs`: a fresh process prepares one kernel, not four (each kernel's first call in a
process costs ~15 ms of LLVM work however small it is; benchmarks/results/stage_solves.md).
The four steps stay kernels of their own too (`grid_bin`, `grid_scatter`, `grid_query`,
`big_query`), made of the same functions."""

import taichi as ti

from .common import F64_2, I32_1, I32_2


@ti.func
def _cell_hash(cx, cy, table):
    h = (ti.cast(cx, ti.i64) * 73856093) ^ (ti.cast(cy, ti.i64) * 19349663)
    return ti.cast((h % table + table) % table, ti.i32)


@ti.func
def _bin(lo: ti.template(), hi: ti.template(), big: ti.template(), h, ox, oy, table, cell: ti.template(),
         bucket: ti.template(), bucket_count: ti.template()):
    for b in range(lo.shape[0]):
        if big[b] == 0:
            cx = ti.cast(ti.floor((0.5 * (lo[b, 0] + hi[b, 0]) - ox) / h), ti.i32)
            cy = ti.cast(ti.floor((0.5 * (lo[b, 1] + hi[b, 1]) - oy) / h), ti.i32)
            cell[b, 0] = cx
            cell[b, 1] = cy
            k = _cell_hash(cx, cy, table)
            bucket[b] = k
            ti.atomic_add(bucket_count[k], 1)


@ti.kernel
def grid_bin(lo: F64_2, hi: F64_2, big: I32_1, h: ti.f64, ox: ti.f64, oy: ti.f64, table: ti.i32,
             cell: I32_2, bucket: I32_1, bucket_count: I32_1):
    """Bin each small box by its centre into a hashed uniform grid of cell size h."""
    _bin(lo, hi, big, h, ox, oy, table, cell, bucket, bucket_count)


@ti.func
def _scatter(big: ti.template(), bucket: ti.template(), bucket_start: ti.template(), bucket_fill: ti.template(),
             sorted_ids: ti.template()):
    for b in range(big.shape[0]):
        if big[b] == 0:
            k = bucket[b]
            s = ti.atomic_add(bucket_fill[k], 1)
            sorted_ids[bucket_start[k] + s] = b


@ti.kernel
def grid_scatter(big: I32_1, bucket: I32_1, bucket_start: I32_1, bucket_fill: I32_1, sorted_ids: I32_1):
    """Counting sort of the small boxes by bucket (bucket_start = exclusive prefix sum)."""
    _scatter(big, bucket, bucket_start, bucket_fill, sorted_ids)


@ti.func
def _boxes_overlap(lo: ti.template(), hi: ti.template(), a, b):
    return (lo[a, 0] <= hi[b, 0] and lo[b, 0] <= hi[a, 0] and
            lo[a, 1] <= hi[b, 1] and lo[b, 1] <= hi[a, 1])


@ti.func
def _query(lo: ti.template(), hi: ti.template(), big: ti.template(), fixed: ti.template(), cell: ti.template(),
           table, bucket_start: ti.template(), sorted_ids: ti.template(), pairs: ti.template(),
           count: ti.template()):
    for b in range(lo.shape[0]):
        if big[b] == 0:
            cx = cell[b, 0]
            cy = cell[b, 1]
            for dx in range(-1, 2):
                for dy in range(-1, 2):
                    k = _cell_hash(cx + dx, cy + dy, table)
                    for s in range(bucket_start[k], bucket_start[k + 1]):
                        o = sorted_ids[s]
                        # the hash may merge cells: keep only boxes of this very cell
                        if o > b and cell[o, 0] == cx + dx and cell[o, 1] == cy + dy:
                            if not (fixed[b] == 1 and fixed[o] == 1) and _boxes_overlap(lo, hi, b, o):
                                n = ti.atomic_add(count[0], 1)
                                if n < pairs.shape[0]:
                                    pairs[n, 0] = b
                                    pairs[n, 1] = o


@ti.kernel
def grid_query(lo: F64_2, hi: F64_2, big: I32_1, fixed: I32_1, cell: I32_2, table: ti.i32,
               bucket_start: I32_1, sorted_ids: I32_1, pairs: I32_2, count: I32_1):
    """Pairs (i < j) of small boxes that overlap, found in the 3×3 neighbouring cells."""
    _query(lo, hi, big, fixed, cell, table, bucket_start, sorted_ids, pairs, count)


@ti.func
def _big(lo: ti.template(), hi: ti.template(), big: ti.template(), big_ids: ti.template(), n_big, fixed: ti.template(),
         pairs: ti.template(), count: ti.template()):
    nb = lo.shape[0]
    for t in range(n_big * nb):
        q = big_ids[t // nb]
        b = t % nb
        # a pair of two big boxes is reported once, from the lower index
        if b != q and (big[b] == 0 or b > q):
            if not (fixed[b] == 1 and fixed[q] == 1) and _boxes_overlap(lo, hi, b, q):
                n = ti.atomic_add(count[0], 1)
                if n < pairs.shape[0]:
                    pairs[n, 0] = ti.min(b, q)
                    pairs[n, 1] = ti.max(b, q)


@ti.kernel
def big_query(lo: F64_2, hi: F64_2, big: I32_1, big_ids: I32_1, fixed: I32_1,
              pairs: I32_2, count: I32_1):
    """Pairs involving a big box (larger than a grid cell), tested against every box."""
    _big(lo, hi, big, big_ids, big_ids.shape[0], fixed, pairs, count)


@ti.kernel
def broad_pairs(lo: F64_2, hi: F64_2, big: I32_1, h: ti.f64, ox: ti.f64, oy: ti.f64, table: ti.i32,
                cell: I32_2, bucket: I32_1, bucket_count: I32_1, bucket_start: I32_1, bucket_fill: I32_1,
                sorted_ids: I32_1, big_ids: I32_1, n_big: ti.i32, fixed: I32_1, pairs: I32_2, count: I32_1):
    """`grid_bin`, the prefix sum of the bucket counts (``bucket_start``, table + 1 entries),
    `grid_scatter`, `grid_query` and `big_query` (of ``big_ids[:n_big]``) in one kernel: each
    top-level loop runs after the one before. ``bucket_count``, ``bucket_fill`` and ``count``
    start at zero."""
    _bin(lo, hi, big, h, ox, oy, table, cell, bucket, bucket_count)
    ti.loop_config(serialize=True)
    for k in range(table):  # exclusive prefix sum, in order (np.cumsum's integers)
        bucket_start[k + 1] = bucket_start[k] + bucket_count[k]
    _scatter(big, bucket, bucket_start, bucket_fill, sorted_ids)
    _query(lo, hi, big, fixed, cell, table, bucket_start, sorted_ids, pairs, count)
    _big(lo, hi, big, big_ids, n_big, fixed, pairs, count)
