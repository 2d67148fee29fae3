"""Test helper: start a child as a terminal would, with SIGINT at its default disposition.

A process started in the background by a shell (``cmd &``, ``nohup``) inherits SIGINT ignored,
and CPython then installs no KeyboardInterrupt handler; tests of Ctrl-C pass this as
``preexec_fn`` so that they test the command, not how pytest itself was started.
"""

from __future__ import annotations

import signal


def sigint_as_from_a_terminal() -> None:
    """``preexec_fn`` for :class:`subprocess.Popen`: SIGINT back to SIG_DFL before exec."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
