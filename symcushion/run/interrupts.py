"""Clean ends of a command: SIGTERM and Ctrl-C (SIGINT), and the exit statuses.

This module owns the command line's exit statuses (docs/checks.md, "Exit
statuses"), the :class:`Terminated` exception a signal raises, the handler
that remembers a termination and raises it again until it is reported, and
the test of whether an exception came from a signal. It must not parse
arguments or run commands (``symcushion.cli`` does).
"""
from __future__ import annotations

import signal
import sys
from contextlib import contextmanager

__all__ = ["EXIT_ERRORS", "EXIT_BAD_INPUT", "EXIT_WARNINGS", "EXIT_OUTPUT_EXISTS",
           "EXIT_INTERRUPTED", "TERMINATION_REMINDER", "Terminated", "terminate", "remind",
           "pending", "termination_in", "interrupt_code", "signals_handled"]

#: Exit statuses (docs/checks.md, "Exit statuses"). A command that works
#: returns 0; bad input is 2.
#: A run that gave a finding of severity error (its results are kept and
#: run.json says ``"status": "errors"``); ``check``: the file has errors.
EXIT_ERRORS = 1
#: Bad input: a field, an option, a path (the one-line message names it).
EXIT_BAD_INPUT = 2
#: A run that finished with warnings under --strict.
EXIT_WARNINGS = 3
#: The output folder holds another run's results and --overwrite was not given.
EXIT_OUTPUT_EXISTS = 4
#: Ctrl-C (SIGINT): 128 + 2, as a shell reports it.
EXIT_INTERRUPTED = 128 + signal.SIGINT


class Terminated(SystemExit):
    """Raised by the SIGTERM and SIGINT handler; its code is 128 + the signal number."""


#: Seconds between re-raisings of a termination that has not been reported.
#: A C extension can swallow an exception raised while it runs Python code:
#: SWIG's overload dispatch (CasADi's ``Function.call``) tries each signature
#: and clears the errors of those that fail, so one raise could be lost and the
#: run go on to its end.
TERMINATION_REMINDER = 0.1

_pending: int | None = None     # the exit code of a SIGTERM or SIGINT not yet reported


def terminate(signum, frame):
    """SIGTERM and SIGINT (Ctrl-C) end a command cleanly: temporary files are
    removed, what is complete is kept (a run's finished blocks, an envelope's
    finished batches), and the command line (``symcushion.cli.main``) exits with 128 + the signal number.

    The termination is remembered and raised again every
    :data:`TERMINATION_REMINDER` s (SIGALRM) until the command line (``symcushion.cli.main``) reports it.
    """
    global _pending
    _pending = 128 + signum
    signal.setitimer(signal.ITIMER_REAL, TERMINATION_REMINDER, TERMINATION_REMINDER)
    remind(signal.SIGALRM, frame)


def remind(signum, frame):
    """Raise the pending termination, unless an exception is being handled.

    Code in an ``except``, ``finally`` or ``__exit__`` is cleaning up (a
    propagating termination, or an error on its way to the command line (``symcushion.cli.main``)); it is
    never interrupted, so temporary files are always removed.
    """
    if _pending is not None and sys.exc_info()[1] is None:
        raise Terminated(_pending)


def termination_in(exc: BaseException) -> Terminated | None:
    """The :class:`Terminated` behind ``exc``, if the signal caused it.

    A signal handler runs wherever Python next checks for signals, which may
    be inside a C extension calling back into Python (CasADi's ``DM.__array__``
    under NumPy, for one); such callers wrap the exception in a
    ``SystemError``, or replace it (SWIG's ``NotImplementedError`` for "wrong
    number or type of arguments"). A pending SIGTERM, or a termination in the
    chain of causes, means the signal caused it.
    """
    if _pending is not None:
        return Terminated(_pending)
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, Terminated):
            return exc
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return None


def interrupt_code(exc: BaseException) -> int | None:
    """The exit status of an interrupt behind ``exc`` (130 for Ctrl-C, 128 + the
    signal for a termination), None for any other exception."""
    if isinstance(exc, KeyboardInterrupt):
        return EXIT_INTERRUPTED
    term = termination_in(exc)
    return None if term is None else term.code


def pending() -> int | None:
    """The exit code of a termination not yet reported, or None."""
    return _pending


@contextmanager
def signals_handled():
    """SIGTERM and SIGINT end what runs inside as :func:`terminate` says; on the way
    out the previous handlers are back and no termination is pending."""
    global _pending
    _pending = None
    previous = {sig: signal.signal(sig, terminate) for sig in (signal.SIGTERM, signal.SIGINT)}
    previous_alarm = signal.signal(signal.SIGALRM, remind)
    try:
        yield
    finally:
        if _pending is not None:
            signal.setitimer(signal.ITIMER_REAL, 0)
        _pending = None
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        signal.signal(signal.SIGALRM, previous_alarm)
