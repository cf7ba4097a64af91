"""The thread budget every stage reads: one place for $FLASHBRDF_THREADS.

A batch or Dask worker sets FLASHBRDF_THREADS to its share of the cores (pipeline.batch,
pipeline.dask_engine); a command on its own uses the cores, up to what each kind of work gains
from (the caller's cap).
"""

import os


def thread_budget(cap):
    """Threads (int >= 1) for one kind of work: $FLASHBRDF_THREADS when it is a positive integer,
    else the cores, at most `cap`. A value that is not a positive integer is ignored, as unset."""
    value = os.environ.get("FLASHBRDF_THREADS", "").strip()
    if value.isdigit() and int(value) > 0:
        return int(value)
    return max(1, min(os.cpu_count() or 1, cap))
