"""One BLAS thread for inference's small dense products, through one cached threadpool controller.

Why: a prediction's products are vector-matrix ((N,)·(N, 24069) for 121 training tables) or small
least squares. Two OpenBLAS threads gain nothing there and, beside any other busy process, lose a
lot: one such product took 12 ms on two threads at load 5.6 and 0.4 ms on one. A single thread also
keeps results independent of the core count: a threaded reduction sums in another order, and an
iterative fit carries that last-bit difference on (noll's robust fit moved by up to 4e-9).
threadpoolctl's ThreadpoolController is built once (inspecting the loaded libraries takes ~4 ms,
too much to repeat per prediction), after numpy and scipy have loaded their BLAS.
"""

import functools

from threadpoolctl import ThreadpoolController

_controller = None


def one_blas_thread():
    """A context manager limiting every loaded BLAS/OpenMP pool to one thread inside it."""
    global _controller
    if _controller is None:
        _controller = ThreadpoolController()
    return _controller.limit(limits=1)


def on_one_blas_thread(fn):
    """Decorator: every call of fn runs inside one_blas_thread(), so its products sum in the same
    order on any core count (Table 1's loop and its Dask workers then agree bit for bit)."""
    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        with one_blas_thread():
            return fn(*args, **kwargs)
    return wrapper
