"""`ddatai.kernel_prep`: the quicker preparation of the kernels' first calls gives Taichi's own
values — every source-position message of every node of ddatai's step kernels, the one-line
wrap against ``textwrap.TextWrapper``, and a function's source read once."""

import textwrap

import numpy as np
import pytest

ti = pytest.importorskip("taichi")


def _dummy_args(kernel):
    """Arguments of the right kinds for a kernel (ndarrays of its dtypes and ranks, scalars, True
    for a template): enough to prepare it, never launched."""
    from taichi.types.ndarray_type import NdarrayType

    args = []
    for arg in kernel.arguments:
        note = arg.annotation
        if isinstance(note, NdarrayType):
            dtype = {ti.f64: np.float64, ti.i32: np.int32, ti.i8: np.int8}[note.dtype]
            args.append(np.zeros((1,) * note.ndim, dtype=dtype))
        elif isinstance(note, ti.template):
            args.append(True)
        else:
            args.append(0)
    return args


def test_every_message_of_the_step_kernels_is_taichis():
    from taichi.lang import kernel_impl
    from taichi.lang.ast import ast_transformer_utils

    from ddatai import backend, kernel_prep

    backend.ensure("cpu")
    assert kernel_prep.install()
    import ddatai.kernels as kernels

    context = ast_transformer_utils.ASTTransformerContext
    quick = context.get_pos_info
    original = quick.original
    seen, wrong = [0], []

    def compared(self, node):
        mine, theirs = quick(self, node), original(self, node)
        seen[0] += 1
        if mine != theirs:
            wrong.append((mine, theirs))
        return theirs

    names = [n for n in kernels.__all__ if n.islower()]
    context.get_pos_info = compared
    try:
        for name in names:
            primal = getattr(kernels, name)._primal
            fresh = kernel_impl.Kernel(primal.func, primal.autodiff_mode)  # prepared anew, never launched
            fresh.ensure_compiled(*_dummy_args(fresh))
    finally:
        context.get_pos_info = quick
    assert len(names) == 15
    assert seen[0] > 5000  # every node of the 15 kernels, their @ti.func inlined at each call
    assert wrong == []


@pytest.mark.parametrize("text", [
    "", " ", "   ", "x", "  x", "x  ", "  a = b - c  ", "-" * 80, "a" * 80, "a" * 81, "a " * 40, "a " * 41,
    "    while lo < hi and mem[lo, 0] != kind:  # a-b well-known hyphen-ated words",
    "\tx = 1", "x = 1\x0c", "é = 1", " " * 79 + "^", "^" * 80 + " ", "x" + " " * 90,
])
def test_one_line_is_textwrap(text):
    from ddatai.kernel_prep import _one_line

    mine = _one_line(text)
    assert mine is None or mine == textwrap.TextWrapper(width=80).wrap(text)
    if len(text) <= 80 and text.isascii() and text.isprintable():
        assert mine is not None  # the quick path is taken where it can be


def test_source_read_once_is_the_same():
    from taichi.lang import _wrap_inspect, kernel_impl

    from ddatai import backend, kernel_prep

    backend.ensure("cpu")
    assert kernel_prep.install() and kernel_prep.install()  # idempotent
    import ddatai.kernels as kernels

    func = kernels.narrow_phase._primal.func
    assert kernel_impl.getsourcelines(func) == _wrap_inspect.getsourcelines(func)
    assert kernel_impl.getsourcelines(func) == _wrap_inspect.getsourcelines(func)  # from the cache
    assert kernel_impl.getsourcefile(func) == _wrap_inspect.getsourcefile(func)
