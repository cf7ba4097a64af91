"""The Dask engine behind `batch` and `evaluate --workers/--scheduler`: one place that opens a client.

Locally it is a `LocalCluster` of worker processes, one Dask thread each; on a cluster it is the
address of a running `dask scheduler`. The cores are shared out: each of N local workers gets
cores // N threads (at least 1) for its BLAS/OpenMP pools and for FLASHBRDF_THREADS (the renderer's
and infer's own thread pools), so N workers on N cores do not oversubscribe them, and a batch of one
capture on one worker still renders on every core as `run` does. Tasks run inside
`worker_threads()`, which applies that limit, and 1 on workers started by hand on other machines.
"""

import contextlib
import logging
import os
import socket
import warnings

from flashbrdf.files.errors import InputError
from flashbrdf.files.threads import thread_budget

THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
                    "FLASHBRDF_THREADS")
# A task whose worker dies is retried once, on another worker, then marked failed (KilledWorker).
# Dask's default is 3; this holds for the local cluster. A running scheduler keeps its own setting
# (DASK_DISTRIBUTED__SCHEDULER__ALLOWED_FAILURES=1 when it is started gives the same rule).
ALLOWED_FAILURES = 1
CONNECT_TIMEOUT = "20s"
PROBE_TIMEOUT_S = 5.0  # a TCP handshake with a live scheduler takes milliseconds, even remote
# --workers starts that many processes on this machine (each a Python with numpy, ~150 MB): a
# typo such as 100000 forked until the machine gave out. Spread work wider with --scheduler.
MAX_WORKERS = 256


def check_engine_options(workers=None, scheduler=None):
    """Bad --workers / --scheduler values as InputError, before any work."""
    if workers is not None and workers < 1:
        raise InputError("--workers", f"must be at least 1, got {workers}")
    if workers is not None and workers > MAX_WORKERS:
        raise InputError("--workers", f"must be at most {MAX_WORKERS} (worker processes on this "
                                      f"machine), got {workers}; use --scheduler for more")
    if scheduler is not None and not scheduler.strip():  # "" would silently mean a local cluster
        raise InputError("--scheduler", "is empty; give tcp://HOST:PORT")
    if workers is not None and scheduler:
        raise InputError("--workers", "give either --workers (a local cluster) or --scheduler, "
                                      "not both")


def threads_per_worker(workers, cores=None):
    """Threads (int >= 1) each of `workers` worker processes on one machine of `cores` cores
    (default: this one's) may use: the cores shared out, at least one each."""
    return max(1, (cores or os.cpu_count() or 1) // max(1, workers))


def worker_env(threads):
    """{variable: value} limiting BLAS/OpenMP pools and FLASHBRDF_THREADS to `threads`."""
    return {name: str(threads) for name in THREAD_VARIABLES}


@contextlib.contextmanager
def dask_client(workers=None, scheduler=None):
    """Yield a `distributed.Client`: to `scheduler` if given, else to a new LocalCluster of
    `workers` processes (default: the number of cores), each limited to
    threads_per_worker(workers) BLAS and render threads, closed on exit."""
    import dask
    from distributed import Client, LocalCluster
    if scheduler:
        _probe_scheduler(scheduler)
        try:
            client = Client(scheduler, timeout=CONNECT_TIMEOUT)
        except (OSError, TimeoutError, ValueError) as err:
            raise InputError("--scheduler", f"cannot reach a Dask scheduler at {scheduler}: "
                                            f"{str(err).splitlines()[0] if str(err) else err}")
        try:
            yield client
        finally:
            _close(client)
        return
    # Dask's nanny also sets MALLOC_TRIM_THRESHOLD_=65536 in its workers; that fixes glibc's
    # mmap threshold, so every large numpy temporary is a fresh mmap: the renderer ran 2x slower
    # (10.7 s against 5.9 s on the sample capture). Keep the BLAS limits, drop that one.
    # The thread limits go in before the worker process starts: OpenBLAS sizes its pool when
    # numpy is imported.
    workers = workers or os.cpu_count() or 1
    env = worker_env(threads_per_worker(workers))
    spawn_env = {k: v for k, v in dask.config.get("distributed.nanny.pre-spawn-environ").items()
                 if k != "MALLOC_TRIM_THRESHOLD_"} | env
    # Dask's statistical profiler samples the task thread's stack every 10 ms: ~1 s of CPU in a
    # capture's ~11 (measured in a 1-worker cluster, 3 captures), for a profile nobody reads.
    with dask.config.set({"distributed.scheduler.allowed-failures": ALLOWED_FAILURES,
                          "distributed.nanny.pre-spawn-environ": spawn_env,
                          "distributed.worker.profile.enabled": False}), \
            warnings.catch_warnings():
        # The scheduler's HTTP endpoint moves to a free port when 8787 is taken (another
        # cluster on this host): not worth a warning on the user's terminal.
        warnings.filterwarnings("ignore", message="Port .* is already in use")
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                               dashboard_address=None, silence_logs=logging.CRITICAL, env=env)
    try:
        client = Client(cluster)
        try:
            yield client
        finally:
            _close(client)
    finally:
        _close(cluster)


def _probe_scheduler(address, timeout=PROBE_TIMEOUT_S):
    """InputError naming --scheduler at once when nothing accepts a TCP connection at a tcp://
    or tls:// ADDRESS (default port 8786): Dask's Client would retry for CONNECT_TIMEOUT."""
    from distributed.comm.addressing import parse_address, parse_host_port
    try:
        scheme, location = parse_address(address)
        if scheme not in ("tcp", "tls"):
            return
        host, port = parse_host_port(location, default_port=8786)
    except (ValueError, TypeError) as err:
        raise InputError("--scheduler", f"not a Dask scheduler address ({err}); expected "
                                        "tcp://HOST:PORT") from None
    try:
        socket.create_connection((host or "127.0.0.1", port), timeout=timeout).close()
    except OSError as err:
        raise InputError("--scheduler", f"cannot reach a Dask scheduler at {address}: "
                                        f"{err.strerror or err}") from None


def _close(thing):
    """Close a client or cluster once the work is done. On a loaded machine a worker process can
    take longer than Dask's few seconds to exit; that must not turn a finished run into a
    traceback (the processes are the nanny's daemonic children and end with it)."""
    with contextlib.suppress(TimeoutError):
        thing.close()


@contextlib.contextmanager
def worker_threads():
    """Inside the block, BLAS/OpenMP pools and FLASHBRDF_THREADS are limited to this worker's
    share of the cores: $FLASHBRDF_THREADS as dask_client set it for a local worker, else 1 (a
    worker started by hand, which may share its machine with others; a value that is not a
    positive integer counts as unset, files.threads)."""
    from threadpoolctl import threadpool_limits
    before = os.environ.get("FLASHBRDF_THREADS")
    threads = thread_budget(cap=1)
    os.environ["FLASHBRDF_THREADS"] = str(threads)
    try:
        with threadpool_limits(limits=threads):
            yield threads
    finally:
        if before is None:
            os.environ.pop("FLASHBRDF_THREADS", None)
        else:
            os.environ["FLASHBRDF_THREADS"] = before
