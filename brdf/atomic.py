"""Atomic file output: write to a temporary file beside the target, then rename.

A crash or an error part-way leaves no partial output file behind.
"""

import contextlib
import os
import tempfile


@contextlib.contextmanager
def atomic_path(path, suffix=None):
    """Yield a temporary path in the target's folder; rename it to `path` on success.

    `suffix` defaults to the target's own extension, so writers that choose a format from the
    file name (OpenImageIO, OpenCV, matplotlib) still see the right one.
    """
    path = os.fspath(path)
    folder = os.path.dirname(os.path.abspath(path))
    created = make_parents(folder)
    if suffix is None:
        # the text from the name's last dot: os.path.splitext skips leading dots, so it gives
        # "..exr" (a reference photo "..exr" renders to OUT_DIR/..exr) no extension, and the
        # writers that choose a format from the name (OpenImageIO) then found none
        name = os.path.basename(path)
        dot = name.rfind(".")
        suffix = name[dot:] if dot > 0 else ""
    fd, tmp = tempfile.mkstemp(prefix="." + os.path.basename(path) + ".", suffix=".part" + suffix,
                               dir=folder)
    os.close(fd)
    # mkstemp makes the file private (0600); the output should get the usual umask permissions.
    os.chmod(tmp, 0o666 & ~current_umask())
    try:
        yield tmp
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
    for f in reversed(created):
        os.makedirs(f, exist_ok=True)
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
