"""The fused engine's rows (`ddatai.fused.pack.row_order`): the free blocks in the order whose
envelope takes the skyline factorisation the least work (Σ over block-rows of the envelope's
width squared, `envelope_work`), reverse Cuthill–McKee or the blocks sorted along an axis."""

from __future__ import annotations

import numpy as np

import ddatai as dd
from ddatai.fused.pack import envelope_work, row_order


def _grid(n: int):
    """n × n unit blocks on a fixed base: each touches its eight neighbours (edges and corners)."""
    sc = dd.Scene(gravity=9.81)
    rock = dd.Material(density=2600.0, young=1e9, poisson=0.25)
    sc.add_block([(-1.0, -1.0), (n + 1.0, -1.0), (n + 1.0, 0.0), (-1.0, 0.0)], material=rock, fixed=True)
    for j in range(n):
        for i in range(n):
            sc.add_block([(i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1)], material=rock)
    return dd.build_model(sc, dd.Params())


def test_envelope_work_of_a_chain_in_its_own_order():
    """A chain 0–1–…–(n−1) numbered along itself: every block-row but the first reaches back one
    block (width 2), so the work is 1 + 4(n − 1)."""
    n = 7
    i, j = np.arange(n - 1), np.arange(1, n)
    assert envelope_work(np.arange(n), i, j) == 1 + 4 * (n - 1)
    # numbered from both ends inwards, rows reach back further
    assert envelope_work(np.array([0, 6, 1, 5, 2, 4, 3]), i, j) > 1 + 4 * (n - 1)


def test_a_grid_of_blocks_is_numbered_row_by_row():
    """On an n × n grid whose blocks touch their eight neighbours, rows (or columns) of the grid
    give the least work: block (r, c) of a row r ≥ 1 reaches back to (r − 1, c − 1), n + 2 blocks
    (n + 1 at c = 0); in the first row 2 (1 at c = 0). Reverse Cuthill–McKee's anti-diagonal
    fronts take more."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import reverse_cuthill_mckee

    n = 8
    model = _grid(n)
    order = row_order(model, model.initial_state().vertex_xy)
    free = np.flatnonzero(~model.block_fixed)
    assert sorted(order.tolist()) == free.tolist()
    row_major = 1 + 4 * (n - 1) + (n - 1) * ((n + 1) ** 2 + (n - 1) * (n + 2) ** 2)
    # the grid's coupled pairs, by the blocks' rows and columns (block 1 + r·n + c)
    r, c = np.divmod(free - 1, n)
    pairs = [(a, b) for a in range(len(free)) for b in range(a + 1, len(free))
             if max(abs(r[a] - r[b]), abs(c[a] - c[b])) == 1]
    i, j = np.array(pairs).T
    at = np.searchsorted(free, order)
    assert envelope_work(at, i, j) == row_major
    graph = coo_matrix((np.ones(2 * len(i)), (np.r_[i, j], np.r_[j, i])), shape=(len(free),) * 2).tocsr()
    assert envelope_work(reverse_cuthill_mckee(graph, symmetric_mode=True), i, j) > row_major
