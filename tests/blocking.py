"""Test helper: fail a test that blocks (a FIFO opened for reading waits for a writer forever)."""

from __future__ import annotations

import contextlib
import signal


@contextlib.contextmanager
def bounded(seconds: int = 10):
    """Raise TimeoutError in the body after ``seconds`` (SIGALRM; main thread only)."""
    def alarm(signum, frame):
        raise TimeoutError(f"blocked for more than {seconds} s")
    previous = signal.signal(signal.SIGALRM, alarm)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)
