"""Resolve the docstrings' short references the way a reader of the source reads them.

The docstrings of ddatai and kgm name other objects in backticks relative to where they are
written: `GifStream` in ``ddatai/render/__init__.py``, `kernels.violations` in ``ddatai/step.py``,
`ddatai.start` for a module. Sphinx resolves a reference from the page's module only (and the
public API pages are under ``ddatai`` and ``kgm``, not the defining modules), so such a
reference would be reported as broken although its target is documented.

When Python-domain resolution fails, this looks for documented objects whose full name is the
target or ends with ``.target`` (a call's ``()`` dropped; then with the target's module path
shortened, down to its last two components), and links the unique one, the one
in the referring package, or the shortest (the public name: ``ddatai.Results`` before
``ddatai.results.Results``). A target that names no documented object stays broken, and the
build (``-W -n``) fails on it.
"""

from __future__ import annotations

from sphinx.util.nodes import make_refnode


def _candidates(domain, target: str) -> list[str]:
    """Documented names that are ``target`` or end with ``.target``; failing that, with its
    last two or more components (``ddatai.step.Stepper.solve`` is documented as
    ``ddatai.Stepper.solve``, the public name of the same class)."""
    parts = target.split(".")
    for k in range(len(parts), 1 if len(parts) > 2 else 0, -1):
        tail = ".".join(parts[-k:])
        names = [n for n in domain.objects if n == tail or n.endswith("." + tail)]
        if names:
            return names
    return []


def _resolve(app, env, node, contnode):
    if node.get("refdomain") != "py":
        return None
    target = node.get("reftarget", "")
    if not target or target.startswith(("~", "!")):
        return None
    target = target.removesuffix("()")
    domain = env.get_domain("py")
    names = _candidates(domain, target)
    if not names:
        return None
    package = (node.get("py:module") or "").split(".")[0]
    same = [n for n in names if n.split(".")[0] == package] or names
    best = min(same, key=lambda n: (n.count("."), len(n), n))
    entry = domain.objects[best]
    return make_refnode(app.builder, node["refdoc"], entry.docname, entry.node_id, contnode, best)


def setup(app):
    # after the Python domain and intersphinx have had their turn
    app.connect("missing-reference", _resolve, priority=900)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
