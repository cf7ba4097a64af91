"""Where a batch task's prints go: each worker thread's stdout and stderr to that capture's
log file (OUT_DIR/logs/<capture>.log), since a worker may run several tasks on threads at once."""

import contextlib
import io
import sys
import threading
from pathlib import Path


class ThreadOutput(io.TextIOBase):
    """A stand-in for sys.stdout / sys.stderr that sends each thread's text to that thread's log
    file, if it has one (a worker may run several tasks on threads at once)."""

    def __init__(self, fallback):
        self.fallback, self.local = fallback, threading.local()

    def write(self, text):
        target = getattr(self.local, "file", None) or self.fallback
        return target.write(text)

    def flush(self):
        (getattr(self.local, "file", None) or self.fallback).flush()

    def isatty(self):
        return False


ROUTING_LOCK = threading.Lock()


@contextlib.contextmanager
def output_to(log_file):
    """Send this thread's stdout and stderr to `log_file` (appended) inside the block."""
    with ROUTING_LOCK:
        for stream in ("stdout", "stderr"):
            if not isinstance(getattr(sys, stream), ThreadOutput):
                setattr(sys, stream, ThreadOutput(getattr(sys, stream)))
    Path(log_file).parent.mkdir(parents=True, exist_ok=True)
    with open(log_file, "a", encoding="utf-8", buffering=1) as f:
        sys.stdout.local.file = sys.stderr.local.file = f
        try:
            yield f
        finally:
            sys.stdout.local.file = sys.stderr.local.file = None
