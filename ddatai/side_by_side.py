"""Many small computations run side by side, their regular NumPy work done once for all of them
(docs/method/dda.md §8.12; docs/guide/performance.md, "Batched studies").

The members of a kgm batch — the samples of a probabilistic study, the probes of a bisection
round — are each settled by their own equilibrium stage (`ddatai.start.settle`). A small
model's stage is hundreds of NumPy calls on arrays of a few contacts, each costing its fixed
overhead whatever its size; the members share their geometry, so their arrays have the same
shapes and the same calls, one member after the other.

`run` runs each member's computation in its own greenlet (a coroutine with its own stack, the
``greenlet`` package): the member's code is the code that runs alone — every decision of its
stage made by the same functions, in the same order — and where it reaches one of the *side by
side operations* (``operation``: the contact assembly, the contact law), it hands its arguments
to the scheduler and waits. When every member waits (or has finished), the scheduler takes the
largest group of members waiting at the same operation with the same constants, evaluates
the operation once over their arrays concatenated with a member axis (`ddatai.stage_batch`:
element-wise terms and scatters whose entries of one member are added in that member's own
order, so each member gets its own floats to the bit), and resumes them with their results.
A member whose control flow goes its own way simply waits less often with the others.

Without ``greenlet`` installed, or with a single member, the computations run one after the
other (the same results). Side by side, a member's wall-clock records (`StartRecord.wall_time`)
count the time of the members beside it too.
"""

from __future__ import annotations

from collections import Counter
from itertools import accumulate
from typing import Callable

import numpy as np

#: run members side by side where greenlet is installed (False: one after the other, as without
#: it; the benchmarks' reference)
ENABLED = True
#: whether members are running side by side somewhere (checked first: costs nothing otherwise)
ACTIVE = 0
#: {name: the plain function} of the side by side operations (`operation`)
_PLAIN: dict = {}
#: {name: (group, batched)} (`register`): ``group(*args, **kwargs)`` the constants that members
#: must share to be evaluated together (hashable; None: evaluated alone), ``batched(requests)``
#: the results, one a request, each request the ``(args, kwargs)`` of one member's call (an
#: exception instance among them is raised in that member)
_BATCHED: dict = {}
#: {(name, whether members were evaluated together): evaluations} since the process started
EVALUATIONS: Counter = Counter()
_Member = None      # the greenlet class of a member (`_greenlets`)
_current = None     # greenlet.getcurrent


def available() -> bool:
    """Whether members can run side by side (the ``greenlet`` package is installed)."""
    return _greenlets()


def _greenlets() -> bool:
    """Import greenlet once (not at ``import ddatai``: it stays cheap)."""
    global _Member, _current
    if _Member is None:
        try:
            from greenlet import getcurrent, greenlet
        except ImportError:  # optional: without it the members run one after the other
            _Member = False
            return False

        class Member(greenlet):
            """A member's greenlet (its parent is the scheduler's)."""

        _Member, _current = Member, getcurrent
    return _Member is not False


class _Request:
    __slots__ = ("name", "group", "args", "kwargs")

    def __init__(self, name, group, args, kwargs):
        self.name, self.group, self.args, self.kwargs = name, group, args, kwargs


def operation(name: str) -> Callable:
    """Decorate a function as the side by side operation ``name``: called from a member running
    side by side (`run`) where its group (`register`) is not None, it waits for the scheduler,
    which evaluates the batched implementation over the waiting members of one group;
    otherwise, and outside `run`, it is the function itself."""
    def wrap(fn):
        _PLAIN[name] = fn

        def side_by_side(*args, **kwargs):
            if ACTIVE and type(_current()) is _Member and name in _BATCHED:
                key = _BATCHED[name][0](*args, **kwargs)
                if key is not None:
                    return _current().parent.switch(_Request(name, key, args, kwargs))
            return fn(*args, **kwargs)

        side_by_side.__wrapped__ = fn
        side_by_side.__name__, side_by_side.__qualname__ = fn.__name__, fn.__qualname__
        side_by_side.__doc__, side_by_side.__module__ = fn.__doc__, fn.__module__
        return side_by_side
    return wrap


def bound(args, kwargs, names) -> list | tuple:
    """A request's arguments in the order of ``names``, the parameters of the operation's plain
    function (None where left out): how a ``group`` or ``batched`` reads a member's call."""
    if not kwargs and len(args) == len(names):
        return args  # every argument given by position (read only)
    out = list(args) + [None] * (len(names) - len(args))
    for k, v in kwargs.items():
        out[names.index(k)] = v
    return out


def offsets(sizes) -> np.ndarray:
    """Where each member's entries start in the concatenation of its arrays of ``sizes``."""
    sizes = sizes.tolist() if isinstance(sizes, np.ndarray) else list(sizes)
    return np.array([0, *accumulate(sizes[:-1])], np.int64) if sizes else np.zeros(0, np.int64)


def register(name: str, group: Callable, batched: Callable) -> None:
    """The group and the batched implementation of the operation ``name`` (`operation`; the
    equilibrium stage's are `ddatai.stage_batch`'s, registered where it is imported). An
    operation without them runs alone in each member."""
    _BATCHED[name] = (group, batched)


def _evaluate(name: str, requests: list) -> list:
    """The results of ``requests`` of operation ``name``: batched, or each alone where there is
    one or where the batched implementation raises (an error then goes to its own member)."""
    plain = _PLAIN[name]
    EVALUATIONS[name, len(requests) > 1] += 1
    if len(requests) > 1:
        try:
            return _BATCHED[name][1](requests)
        except Exception:  # each alone: the error, if any, is then its member's own
            pass
    outs = []
    for args, kwargs in requests:
        try:
            outs.append(plain(*args, **kwargs))
        except Exception as err:
            outs.append(_Raise(err))
    return outs


_START = object()  # a member's first switch: its call begins


class _Raise:
    """An operation's error, raised in the member that called it."""

    __slots__ = ("err",)

    def __init__(self, err):
        self.err = err


def run(calls) -> list:
    """The results of ``calls`` (callables without arguments), each computed as alone, side by
    side where the ``greenlet`` package is installed (module docstring). A call that raises
    raises here once every other has finished (the first such error in the order of
    ``calls``)."""
    global ACTIVE
    calls = list(calls)
    if len(calls) < 2 or not ENABLED or not _greenlets() or type(_current()) is _Member:
        return [c() for c in calls]
    results: list = [None] * len(calls)
    errors: dict = {}
    # the members waiting, by operation and group, in the order they came to wait (a group
    # goes when it is evaluated, and comes again with the first member that waits in it)
    waiting: dict = {}
    members = [_Member(c) for c in calls]

    def advance(k, value):
        try:
            if value is _START:
                out = members[k].switch()
            else:
                out = members[k].throw(value.err) if isinstance(value, _Raise) else members[k].switch(value)
        except Exception as err:  # the member's own error, raised once the others finish
            errors[k] = err
            return
        if isinstance(out, _Request) and not members[k].dead:
            at = waiting.get((out.name, out.group))
            if at is None:
                waiting[out.name, out.group] = [(k, out)]
            else:
                at.append((k, out))
        else:
            results[k] = out

    ACTIVE += 1
    try:
        for k in range(len(calls)):
            advance(k, _START)
        while waiting:
            key = max(waiting, key=lambda g: len(waiting[g]))  # the largest group, the first such
            group = waiting.pop(key)
            outs = _evaluate(key[0], [(r.args, r.kwargs) for _, r in group])
            for (k, _), out in zip(group, outs):
                advance(k, out)
    finally:
        ACTIVE -= 1
        for g in members:  # members left waiting by an error of the scheduler's own are ended
            if not g.dead:
                g.throw()
    for k in sorted(errors):
        raise errors[k]
    return results
