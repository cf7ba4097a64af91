"""Atomic file output: write to a temporary file beside the target, then rename.

A crash or an error part-way leaves no partial output file behind.
"""

import contextlib
import errno
import os
import tempfile

from flashbrdf.files.signals import raise_if_signalled

# What creating a file or folder at a path the user gave fails with when that path cannot hold
# one (a name too long, a read-only or pseudo filesystem such as /proc, no permission): bad input
# naming the path, not a traceback. A full disk or an I/O error stays an error of its own (exit 1).
UNWRITABLE_ERRNOS = {errno.ENAMETOOLONG, errno.EACCES, errno.EPERM, errno.EROFS, errno.ENOENT,
                     errno.ENOTDIR, errno.EISDIR, errno.EINVAL}


def unwritable(path, err):
    """InputError naming `path` for an OSError `err` of UNWRITABLE_ERRNOS, else None."""
    if getattr(err, "errno", None) not in UNWRITABLE_ERRNOS:
        return None
    from flashbrdf.files.errors import InputError
    return InputError(path, f"cannot be written there ({err.strerror or err})")


def name_extension(name):
    """The extension of a file name, from its last dot ("..exr" -> ".exr", "a.b.exr" -> ".exr",
    ".hidden" -> ""): os.path.splitext skips leading dots, so it gives "..exr" none, and writers
    that choose a format from the name (OpenImageIO) then find none."""
    dot = name.rfind(".")
    return name[dot:] if dot > 0 else ""


@contextlib.contextmanager
def atomic_path(path, suffix=None):
    """Yield a temporary path in the target's folder; rename it to `path` on success.

    `suffix` defaults to the target's own extension, so writers that choose a format from the
    file name (OpenImageIO, OpenCV, matplotlib) still see the right one.
    """
    path = os.fspath(path)
    folder = os.path.dirname(os.path.abspath(path))
    try:
        created = make_parents(folder)
    except OSError as err:
        raise unwritable(path, err) or err from None
    if suffix is None:
        suffix = name_extension(os.path.basename(path))  # a reference photo "..exr" -> "..exr"
    try:
        fd, tmp = tempfile.mkstemp(prefix="." + os.path.basename(path) + ".",
                                   suffix=".part" + suffix, dir=folder)
    except OSError as err:
        remove_empty(created)
        raise unwritable(path, err) or err from None
    os.close(fd)
    # mkstemp makes the file private (0600); the output should get the usual umask permissions.
    os.chmod(tmp, 0o666 & ~current_umask())
    try:
        yield tmp
        raise_if_signalled()
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.remove(tmp)
        remove_empty(created)
        raise


def make_parents(folder):
    """Create `folder` and its missing parents; return those created, deepest first (so a failed
    write can take them back with remove_empty and leave no new folder behind)."""
    created = []
    folder = os.path.abspath(folder)
    while not os.path.isdir(folder):
        created.append(folder)
        folder = os.path.dirname(folder)
    try:
        for f in reversed(created):
            os.makedirs(f, exist_ok=True)
    except OSError:  # none of the folders made so far is left behind
        remove_empty(created)
        raise
    return created


def remove_empty(folders):
    """Remove each folder of `folders` (deepest first) that is still empty."""
    for folder in folders:
        with contextlib.suppress(OSError):
            os.rmdir(folder)


def current_umask():
    """The process umask (read by setting and restoring it)."""
    umask = os.umask(0)
    os.umask(umask)
    return umask


def write_text(path, text):
    """Write `text` (str) to `path` atomically."""
    with atomic_path(path) as tmp:
        with open(tmp, "w", encoding="utf-8", newline="\n") as f:
            f.write(text)
