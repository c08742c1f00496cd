"""Quicker first calls of Taichi kernels in a fresh process, the results unchanged.

Taichi 1.7 prepares a kernel at its first call in every process, even when the offline cache
holds its machine code: it reads the kernel's source, transforms its AST with every
``@ti.func`` inlined at each of its call sites, and only then hashes the IR built for the
cache's key. Two parts of that transformation do the same work again and again (measured with
``benchmarks/cold_start.py``, the grid of 1,600 blocks: 17,402 AST nodes at 13 kernels' first
calls, 5,141 distinct):

- every node gets a source-position message for errors (``ASTTransformerContext.get_pos_info``),
  built eagerly with a fresh ``textwrap.TextWrapper`` per node: ~0.33 s of the kernels' 0.69 s of
  Python preparation;
- every inlined call re-reads the function's source (``inspect.getsourcelines``, which
  tokenises the file from the function's line on).

`install` replaces both with versions that return the same values: a message is built once
for each place in the source (the inputs it is made of are the key) and, for a line that fits
TextWrapper's 80 columns, without the wrapper (what ``TextWrapper(width=80).wrap`` returns for
one line of plain text is the line without trailing blanks; tests/test_kernel_prep.py checks
the messages against Taichi's over every node of ddatai's kernels), and a function's source
is read once a process. The IR, and so the offline cache's
key and the machine code, are the same bit for bit: only Taichi's own bookkeeping is quicker.
Installed by `ddatai.backend.ensure`; a Taichi other than 1.7 is left alone.
"""

from __future__ import annotations

_installed = False
#: the width of Taichi's TextWrapper; a longer line goes to Taichi's own message builder
_WRAP_WIDTH = 80


def _one_line(text: str):
    """``TextWrapper(width=80).wrap(text)`` where it is one line of plain ASCII text, else None."""
    if len(text) > _WRAP_WIDTH or not text.isascii() or not text.isprintable():
        return None  # tabs, control characters (some of which str.strip drops), non-ASCII
    stripped = text.rstrip(" ")
    return [stripped] if stripped else []


def _pos_info(original):
    memo: dict = {}

    def get_pos_info(self, node):
        """``ASTTransformerContext.get_pos_info``: built quickly for a node on one line that fits
        80 columns, by Taichi otherwise; either kept for the next node at the same place."""
        body = getattr(node, "body", None)
        key = (self.file, self.lineno_offset, self.indent, self.func.func.__name__, tuple(self.src),
               type(node).__name__, node.lineno, node.end_lineno, node.col_offset, node.end_col_offset,
               body[0].lineno if isinstance(body, list) and body else None)
        try:
            return memo[key]
        except KeyError:
            pass
        msg = _one_line_info(self, node)
        memo[key] = msg = original(self, node) if msg is None else msg
        return msg

    get_pos_info.original = original
    return get_pos_info


def _one_line_info(self, node):
    """Taichi's message for a node on one line of plain text within 80 columns, else None."""
    if node.lineno != node.end_lineno:
        return None
    code = self.src[node.lineno - 1]
    col_offset = self.indent + node.col_offset
    hint = " " * col_offset + "^" * (self.indent + node.end_col_offset - col_offset)
    hint += " " * (len(code) - len(hint))
    code_lines, hint_lines = _one_line(code), _one_line(hint)
    if code_lines is None or hint_lines is None:
        return None
    msg = f'File "{self.file}", line {node.lineno + self.lineno_offset}, in {self.func.func.__name__}:\n'
    if not code_lines:
        return msg + "\n\n"
    return msg + "".join(c + "\n" + h + "\n" for c, h in zip(code_lines, hint_lines))


def _read_once(original):
    cache: dict = {}

    def read(obj):
        key = getattr(obj, "__code__", None) or obj
        try:
            hit = cache[key]
        except (KeyError, TypeError):
            hit = original(obj)
            try:
                cache[key] = hit
            except TypeError:
                pass
        return (list(hit[0]), hit[1]) if isinstance(hit, tuple) else hit

    read.original = original
    return read


def install() -> bool:
    """Put the quicker preparation in place (once a process). Returns whether it is in place."""
    global _installed
    if _installed:
        return True
    import taichi as ti

    if tuple(ti.__version__[:2]) != (1, 7):
        return False
    from taichi.lang import kernel_impl
    from taichi.lang.ast import ast_transformer_utils

    context = ast_transformer_utils.ASTTransformerContext
    if not all(hasattr(m, n) for m, n in ((context, "get_pos_info"), (kernel_impl, "getsourcelines"),
                                          (kernel_impl, "getsourcefile"))):
        return False
    context.get_pos_info = _pos_info(context.get_pos_info)
    kernel_impl.getsourcelines = _read_once(kernel_impl.getsourcelines)
    kernel_impl.getsourcefile = _read_once(kernel_impl.getsourcefile)
    _installed = True
    return True
