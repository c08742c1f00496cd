"""Functions for worker processes of `ddatai.workers` in tests: light to import (a worker
imports this module to find them), one of them kills its worker process on a chosen item."""

import multiprocessing
import os
import signal


def kill_this_worker() -> None:
    """SIGKILL this process, as the out-of-memory killer would; only a worker process may."""
    if multiprocessing.parent_process() is None:  # the test process itself
        raise RuntimeError("this item kills its worker process: run it on worker processes")
    os.kill(os.getpid(), signal.SIGKILL)


def square(x):
    return x * x


def fails_on_three(x):
    if x == 3:
        raise ValueError("three is refused")
    return x


def kills_on_seven(x):
    """x², except that item 7 kills its worker process, every time."""
    if x == 7:
        kill_this_worker()
    return x * x


def kills_on_seven_in_batch(batch):
    """A batch of items as one item: [(index, x²)]."""
    return [(i, kills_on_seven(x)) for i, x in batch]


def waits_for_mark(arg):
    """Item (k, path): item 0 returns at once; the others wait (up to 60 s) for the file at
    path, which the caller creates when it has item 0's result; True if it came."""
    import time

    k, path = arg
    deadline = time.monotonic() + 60.0
    while k and not os.path.exists(path) and time.monotonic() < deadline:
        time.sleep(0.01)
    return k == 0 or os.path.exists(path)


def frozen_by_keep_for_life(_):
    """The objects the collector leaves out of its passes before and after a study's worker
    keeps what it holds (`kgm.studies.probabilistic._keep_for_life`), twice."""
    import gc

    from kgm.studies.probabilistic import _keep_for_life

    before = gc.get_freeze_count()
    _keep_for_life()
    once = gc.get_freeze_count()
    _keep_for_life()
    return before, once, gc.get_freeze_count()
