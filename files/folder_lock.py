"""One writer at a time in an output folder that a command adds to (batch's OUT_DIR)."""

import contextlib
import os

from flashbrdf.files.errors import InputError


@contextlib.contextmanager
def sole_writer(folder, problem):
    """Hold an exclusive lock on the existing `folder` inside the block; InputError(folder,
    problem) at once if another process holds it. The kernel drops the lock when its process
    dies, so a killed command never leaves the folder locked. On a filesystem without locks
    (some network mounts) the block runs unguarded."""
    import fcntl
    fd = os.open(folder, os.O_RDONLY)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise InputError(folder, problem) from None
        except OSError:
            pass
        yield
    finally:
        os.close(fd)
