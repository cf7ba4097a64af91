"""A progress bar over photos on the terminal: on stderr, only on a terminal (none in a log or a
pipe), and only for more than one photo."""

import sys


def photo_progress(items, what, total=None):
    """`items` wrapped in a tqdm bar labelled `what`; total: their count when `items` has no
    len (a generator)."""
    from tqdm import tqdm  # not at import: `flashbrdf --help` stays light
    count = total if total is not None else (len(items) if hasattr(items, "__len__") else None)
    return tqdm(items, desc=what, unit="photo", total=count, file=sys.stderr,
                disable=(count is not None and count < 2) or not sys.stderr.isatty())
