"""Signals and native stderr for the command line: Ctrl-C and SIGTERM end a command cleanly (its
staged outputs removed, files.outputs), and what C libraries print is held back on bad input.

- handle_signals(): SIGTERM raises Terminated, SIGINT KeyboardInterrupt, in the main thread;
- raise_if_signalled(): before an output is committed, raise what a library swallowed (trimesh's
  optional imports catch BaseException: a SIGTERM landing there would be lost);
- signals_deferred(): hold both while a few renames run (an output is replaced whole or not);
- hold_native_stderr(): libpng, OpenEXR and friends write to fd 2 directly; bad input gets only
  the contract's one stderr line.
"""

import contextlib
import os
import signal
import sys
import tempfile
import threading

from flashbrdf.files.errors import InputError


class Terminated(BaseException):
    """SIGTERM, raised in the main thread so that every `with` block cleans up (exit 143).

    A BaseException like KeyboardInterrupt: no `except Exception` swallows it.
    """


# the signals handle_signals caught during the current command, in order
_received = []


def raise_if_signalled():
    """Raise Terminated (SIGTERM) or KeyboardInterrupt (SIGINT) if one arrived under
    handle_signals, even though the exception its handler raised was swallowed on the way (an
    `except BaseException` without re-raise in a library). Called before an output is committed,
    so a command told to stop never leaves its output."""
    if _received:
        raise Terminated() if _received[-1] == signal.SIGTERM else KeyboardInterrupt()


@contextlib.contextmanager
def signals_deferred():
    """Hold SIGINT and SIGTERM (main thread) while the body runs; they arrive right after."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    held = {signal.SIGINT, signal.SIGTERM}
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, held)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


@contextlib.contextmanager
def hold_native_stderr(drop_on=(InputError,)):
    """Hold what is written to file descriptor 2 while the body runs (libpng, OpenEXR and other C
    libraries print there directly), and pass it on afterwards, unless the body raised one of
    `drop_on`: bad input then gets exactly the one stderr line the contract promises.

    Only when stderr is not a terminal (on a terminal progress bars must show as they go), and
    only in the main thread (fd 2 is the process's: threads running commands would race on it).
    """
    if not _fd_is_file(2) or threading.current_thread() is not threading.main_thread():
        yield
        return
    with contextlib.suppress(AttributeError, OSError, ValueError):
        sys.stderr.flush()
    saved = os.dup(2)
    buffer = tempfile.TemporaryFile()
    os.dup2(buffer.fileno(), 2)
    drop = False
    try:
        yield
    except drop_on:
        drop = True
        raise
    finally:
        with contextlib.suppress(AttributeError, OSError, ValueError):
            sys.stderr.flush()
        os.dup2(saved, 2)
        os.close(saved)
        buffer.seek(0)
        held = buffer.read()
        buffer.close()
        if held and not drop:
            os.write(2, held)


def _fd_is_file(fd):
    try:
        return not os.isatty(fd) and os.fstat(fd) is not None
    except OSError:
        return False


@contextlib.contextmanager
def handle_signals():
    """While the body runs, SIGTERM raises Terminated and SIGINT KeyboardInterrupt in the main
    thread (so staged outputs are cleaned up). SIGINT is set too because a library imported
    earlier (drjit, via mitsuba) may have replaced Python's default handler. Each signal is also
    remembered, so one whose exception a library swallowed still stops the command
    (raise_if_signalled). Outside the main thread (e.g. a Dask worker) nothing changes."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def raise_terminated(signum, frame):
        _received.append(signal.SIGTERM)
        raise Terminated()

    def raise_interrupt(signum, frame):
        _received.append(signal.SIGINT)
        raise KeyboardInterrupt()

    _received.clear()
    previous = signal.signal(signal.SIGTERM, raise_terminated)
    previous_int = signal.signal(signal.SIGINT, raise_interrupt)
    try:
        yield
        raise_if_signalled()  # the command finished, but it was told to stop: it did not succeed
    finally:
        signal.signal(signal.SIGTERM, previous)
        signal.signal(signal.SIGINT, previous_int)
        _received.clear()  # a later command, or library use outside one, starts afresh
