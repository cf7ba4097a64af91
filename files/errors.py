"""Errors for bad user input: the CLI turns them into exit status 2 and one line on stderr."""

import os
import zipfile
import zlib

# What readers of a damaged file raise (a truncated copy, a wrong format, a corrupt member):
# numpy's np.load, zipfile, zlib, json and struct-like parsing. Readers catch this family around
# their decoding and turn it into InputError naming the file.
DECODE_ERRORS = (OSError, ValueError, KeyError, IndexError, EOFError, zipfile.BadZipFile,
                 zlib.error)


class InputError(ValueError):
    """Bad input: names the offending file (or field) and says what is wrong.

    str(err) is the single line the CLI prints, "<where>: <problem>".
    """

    def __init__(self, where, problem):
        # a file name or a JSON key may hold a newline or other control character: escape it
        self.where = _printable(os.fspath(where)) if where is not None else None
        # one line, whatever a library's message holds (libpng and OpenImageIO add newlines)
        problem = "; ".join(part.strip() for part in str(problem).splitlines() if part.strip())
        self.problem = problem
        super().__init__(f"{self.where}: {problem}" if self.where else problem)


def no_file(path, what="file", missing="file not found"):
    """InputError naming `path`, which is no file: "is a folder, not a <what>" for a folder,
    else `missing`."""
    return InputError(path, f"is a folder, not a {what}" if os.path.isdir(path) else missing)


def _printable(text):
    """`text` with each non-printable character escaped as Python would (\\n, \\x00, ...)."""
    if isinstance(text, bytes):
        text = os.fsdecode(text)
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)


def library_error(source, fallback=""):
    """The last error message of an OpenImageIO-like `source` (the module, an ImageInput or an
    ImageOutput: anything with geterror()), stripped, or `fallback` when it is empty. The
    binding decodes the library's bytes as UTF-8, and a damaged file's own bytes quoted in the
    message need not be: then a placeholder, never a UnicodeDecodeError."""
    try:
        message = source.geterror()
    except UnicodeDecodeError:
        return "(the library's message is not UTF-8 text)"
    return message.strip() or fallback
