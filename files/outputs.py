"""Output safety, in one place: no command overwrites or deletes an input, or a folder it did not
make, and a failed command leaves no output behind.

The contract ("Exit status and errors"): an output that is an input, or an output folder that is
or contains an input, is bad input (exit 2); a new file or subfolder inside a capture folder is
fine. Every command states what it reads and writes and calls, before any slow work:

    check_outputs(inputs=[scene_dir, *scene_input_files(scene), brdf], outputs=[out_dir],
                  folders=[out_dir])

and builds a folder output in a temporary sibling that is renamed into place only on success:

    with staged_output_dir(out_dir, force=args.force) as tmp:
        ...write into tmp...

Folders this tool makes carry the marker file MARKER. An existing folder is replaced only when it
is empty, or when it carries the marker and `--force` was given; anything else is refused (exit 2),
so a user's own folder is never deleted. File outputs are written with files.atomic.atomic_path.

Paths are compared both as given (absolute, normalised) and as real paths (symlinks resolved), so
`--out link-to-input` and `--out input-seen-through-a-symlinked-folder` are both caught; existing
files are also compared by inode, which catches hard links.
"""

import contextlib
import errno
import json
import os
import shutil
import tempfile
import time
from pathlib import Path

from flashbrdf.files.atomic import (
    current_umask,
    make_parents,
    name_extension,
    remove_empty,
    unwritable,
)
from flashbrdf.files.errors import InputError
from flashbrdf.files.signals import raise_if_signalled, signals_deferred

MARKER = ".flashbrdf-output"


def _forms(path):
    """The absolute normalised path and the real path of `path` (either may not exist)."""
    path = os.fspath(path)
    return {os.path.normpath(os.path.abspath(path)), os.path.realpath(path)}


def path_inside(child, parent):
    """Whether path `child` is `parent` or lies under it (both absolute, normalised)."""
    return child == parent or child.startswith(parent.rstrip(os.sep) + os.sep)


def _same_file(a, b):
    with contextlib.suppress(OSError):
        return os.path.samefile(a, b)
    return False


def check_output_kind(path, folder):
    """InputError when `path` exists as the wrong kind: a folder where a file is to be written, or
    a file (or anything else) where a folder is to be written."""
    path = os.fspath(path)
    if not folder and path.endswith(tuple({"/", os.sep})):
        raise InputError(path, "ends in a path separator, as a folder would (--out names an "
                               "output file here)")
    if folder and os.path.exists(path) and not os.path.isdir(path):
        raise InputError(path, "exists and is not a folder (--out names an output folder here)")
    if not folder and os.path.isdir(path):
        raise InputError(path, "is a folder (--out names an output file here)")
    # files are renamed into place (files.atomic): that would replace a device, pipe or socket
    # (`--out /dev/stdout` run as root replaced the container's /dev/stdout with a regular file)
    if not folder and os.path.exists(path) and not os.path.isfile(path):
        raise InputError(path, "exists and is not a regular file (a device, pipe or socket); "
                               "--out names a file to write")


def check_outputs(inputs, outputs, folders=()):
    """Refuse (InputError) any output that would touch an input, or is of the wrong kind.

    inputs: paths (files or folders) the command reads; None entries are ignored.
    outputs: every path the command writes (files, and output folders as a whole), sidecars too.
    folders: those of `outputs` that are folders; the others are files.
    Raised when an output is an input, when an output folder is or contains an input, when an
    input folder would be replaced by an output file, or when an output exists as the other kind.
    """
    inputs = [os.fspath(p) for p in inputs if p is not None]
    folder_set = {os.fspath(p) for p in folders}
    written = {}
    for out in (os.fspath(p) for p in outputs):
        if not out:  # would be the current folder
            raise InputError("--out", "is empty; give an output path")
        is_folder = out in folder_set
        out_forms = _forms(out)
        # two outputs at one path (`segment --out x.png --albedo x.exr`: both write x.json): the
        # second would silently replace the first
        twice = next((written[f] for f in out_forms if f in written), None)
        if twice is not None:
            raise InputError(out, f"would be written twice (also as {twice}); give the outputs "
                                  "different names")
        written.update(dict.fromkeys(out_forms, out))
        for src in inputs:
            src_forms = _forms(src)
            if out_forms & src_forms or _same_file(out, src):
                raise InputError(out, f"is an input ({src}); refusing to overwrite it")
            if is_folder and any(path_inside(s, o) for s in src_forms for o in out_forms):
                raise InputError(out, f"output folder contains an input ({src}); refusing to "
                                      "replace it")
        check_output_kind(out, is_folder)
        _check_parent(out)


def _check_parent(path):
    """InputError when the output cannot be made: its nearest existing ancestor is not a folder
    (`--out notes.txt/x.csv`) or cannot be written to."""
    ancestor = os.path.dirname(os.path.abspath(os.fspath(path)))
    while not os.path.lexists(ancestor):
        ancestor = os.path.dirname(ancestor)
    if not os.path.isdir(ancestor):
        raise InputError(path, f"cannot be made: {ancestor} is not a folder")
    _check_name_length(path, ancestor)
    if not os.access(ancestor, os.W_OK | os.X_OK):
        raise InputError(path, f"cannot be made: no permission to write in {ancestor}")


def _check_name_length(path, ancestor):
    """InputError when a name in `path` below its existing `ancestor` is too long for the
    filesystem, counting for the last one what the temporary output beside it adds ("." + name +
    ".XXXXXXXX.part" + extension; the folders above are made as named): found here, before the
    work, not when the result is written."""
    try:
        limit = os.pathconf(ancestor, "PC_NAME_MAX")
    except (OSError, ValueError):
        limit = 255
    names = os.path.relpath(os.path.abspath(os.fspath(path)), ancestor).split(os.sep)
    for k, name in enumerate(names):
        extra = 0 if k < len(names) - 1 else 16 + len(os.fsencode(name_extension(name)))
        if len(os.fsencode(name)) + extra > limit:
            raise InputError(path, f"cannot be made: the name {name[:24]}... is "
                                   f"{len(os.fsencode(name))} bytes long, over the "
                                   f"{limit - extra} this filesystem allows here")


def check_writable_folder(path):
    """InputError when the output folder `path` cannot be written in: an existing folder without
    write permission (or on a read-only filesystem), or one that cannot be made. For a command
    that adds to its OUT_DIR (batch) rather than building a new one aside and renaming it."""
    path = os.fspath(path)
    if not os.path.isdir(path):
        _check_parent(path)
    elif not os.access(path, os.W_OK | os.X_OK):
        raise InputError(path, "cannot be written: no permission to write in it")


def folder_inventory(folder, only=None, skip=()):
    """{path relative to folder (POSIX): size in bytes} of the files below `folder`, but those
    named in `skip`; of the paths in `only` when given (a missing one is left out)."""
    folder = Path(folder)
    if only is not None:
        found = {}
        for rel in only:
            try:
                found[rel] = (folder / rel).stat().st_size
            except OSError:
                pass
        return found
    return {p.relative_to(folder).as_posix(): p.stat().st_size
            for p in sorted(folder.rglob("*")) if p.is_file() and p.name not in skip}


def files_fingerprint(paths):
    """{real path: [size in bytes, mtime in ns], or None for a file that is not there (an
    optional reference photo)}: what tells a later run that an input changed since an output
    was made from it. Keyed by the resolved path, so a link or a `..` names the same file."""
    found = {}
    for path in paths:
        try:
            st = os.stat(path)
        except OSError:
            found[os.path.realpath(path)] = None
            continue
        found[os.path.realpath(path)] = [st.st_size, st.st_mtime_ns]
    return found


def sidecar_json(path):
    """The JSON written beside a file output: SLICE.csv -> SLICE.json (x.json -> x.report.json)."""
    path = os.fspath(path)
    root, ext = os.path.splitext(path)
    return root + ".report.json" if ext.lower() == ".json" else root + ".json"


def check_sidecar_replaceable(path, own_key, record):
    """InputError when the JSON at `path` (a sidecar this command writes) exists and is not this
    command's own earlier `record` (a JSON object holding `own_key`): `extract --out x.csv` then
    `infer x.csv --out x.binary` would otherwise replace extract's x.json, which only extract can
    make again."""
    path = os.fspath(path)
    if not os.path.isfile(path):
        return
    try:
        with open(path, encoding="utf-8") as f:
            earlier = json.load(f)
    except (OSError, UnicodeDecodeError, ValueError):
        earlier = None
    if isinstance(earlier, dict) and own_key in earlier:
        return
    raise InputError(path, f"exists and is not an earlier {record} (another command's output or a "
                           "file of yours); this output would replace it: give --out another name")


def _is_marked(folder):
    return os.path.isfile(os.path.join(folder, MARKER))


def _check_replaceable(target, force):
    """InputError unless the existing `target` may be replaced: missing, an empty folder, or a
    folder this tool made (marker) with force."""
    if not os.path.lexists(target):
        return
    if os.path.islink(target):
        raise InputError(target, "is a symbolic link; give the folder it points to (a link is "
                                 "never replaced)")
    if not os.path.isdir(target):
        raise InputError(target, "exists and is not a folder (--out names an output folder here)")
    if os.path.ismount(target):  # the rename onto it fails (EBUSY) after all the work
        raise InputError(target, "is a mount point, which a new folder cannot replace; give a "
                                 "folder inside it")
    if not os.listdir(target):
        return
    if not _is_marked(target):
        raise InputError(target, f"exists, is not empty and was not made by flashbrdf (no {MARKER}); "
                                 "refusing to replace it")
    if not force:
        raise InputError(target, "exists (an earlier flashbrdf output); pass --force to replace it")


@contextlib.contextmanager
def staged_output_dir(path, force=False, command=None):
    """Yield a fresh temporary folder beside `path`; on success it becomes `path` in one rename.

    path: the output folder. force: replace an existing folder that flashbrdf made.
    command: recorded in the marker file (e.g. "run").
    Checked before the body runs and again at the rename (another process may have written `path`
    meanwhile). On any exception, KeyboardInterrupt and SIGTERM (see handle_signals) included,
    the temporary folder is removed and nothing at `path` changes.
    """
    target = os.path.abspath(os.fspath(path))
    _check_replaceable(target, force)
    parent = os.path.dirname(target)
    created = []
    try:
        created = make_parents(parent)
        tmp = tempfile.mkdtemp(prefix=f".{os.path.basename(target)}.", suffix=".part", dir=parent)
    except OSError as err:  # a name too long, /proc, a read-only filesystem
        remove_empty(created)
        raise unwritable(path, err) or err from None
    try:
        os.chmod(tmp, 0o777 & ~current_umask())
        with open(os.path.join(tmp, MARKER), "w", encoding="utf-8") as f:
            json.dump({"tool": "flashbrdf", "command": command,
                       "created_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}, f)
            f.write("\n")
        yield tmp
        if not os.path.isfile(os.path.join(tmp, MARKER)):
            # written first, so gone only if another process removed the folder under us (a
            # batch client cleaning up after a remote worker): what is left is not whole
            raise RuntimeError(f"{tmp}: removed by another process while it was being built; "
                               "nothing written")
        with signals_deferred():  # no Ctrl-C between moving the old folder away and renaming
            raise_if_signalled()
            _check_replaceable(target, force)
            old = None
            try:
                if os.path.lexists(target) and os.listdir(target):
                    old = tempfile.mkdtemp(prefix=f".{os.path.basename(target)}.",
                                           suffix=".old", dir=parent)
                    os.replace(target, os.path.join(old, "previous"))
                os.replace(tmp, target)
            except OSError as err:
                if err.errno != errno.EBUSY:
                    raise
                # a mount point that os.path.ismount does not see (a bind mount within one
                # filesystem): the rename is refused, the earlier checks could not know
                remove_empty([old] if old else [])
                raise InputError(target, "is a mount point (or in use), which a new folder "
                                         "cannot replace; give a folder inside it") from None
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        remove_empty(created)
        raise
