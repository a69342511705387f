"""Helper threads of a command that leave Ctrl+C to the main thread.

The kernel hands a process's SIGINT to any of its threads that does not block it. Python runs
the handler in the main thread, but only wakes it when the signal reached it: delivered to a
helper (a pipe's pump, a sampler), a main thread asleep or blocked in C stays there until its
call returns — Ctrl+C then waits that long. A helper started here blocks the signals a command
answers (SIGINT, SIGTERM), so they reach the main thread.
"""
from __future__ import annotations

import signal
import threading

#: the signals a command answers in its main thread
ANSWERED = {signal.SIGINT, signal.SIGTERM}


def helper_thread(target, *args, name: str) -> threading.Thread:
    """A started daemon thread running ``target(*args)`` with :data:`ANSWERED` blocked (from
    its first instruction: it inherits the mask its creator holds while starting it)."""
    thread = threading.Thread(target=target, args=args, daemon=True, name=name)
    try:
        previous = signal.pthread_sigmask(signal.SIG_BLOCK, ANSWERED)
    except (AttributeError, OSError, ValueError):     # no POSIX thread signals here
        previous = None
    try:
        thread.start()
    finally:
        if previous is not None:
            signal.pthread_sigmask(signal.SIG_SETMASK, previous)
    return thread
