"""Signal handlers held for a block of code: installed on entry and the previous one restored on
exit, and only in the main thread (Python delivers signals there alone; elsewhere, say a
Ray worker's task thread, the block runs with the handlers it has)."""
from __future__ import annotations

import contextlib
import signal
import threading


@contextlib.contextmanager
def handling(signum: int, handler):
    """`handler(signum, frame)` for `signum` while the block runs."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signum, handler)
    try:
        yield
    finally:
        signal.signal(signum, previous)
