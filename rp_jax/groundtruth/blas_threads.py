"""How many threads NumPy's OpenBLAS uses, set for the span of a block (Sec. III-D matching).

Matching multiplies the descriptors of one image pair at a time (``exact_pairs``): products
of about 1,000 x 130 by 130 x 1,000, too small for OpenBLAS's threads to pay for their
hand-offs. With its default (one thread per core) the matcher of one 40-image viewpoint took
11.1 s of CPU against 2.4 s single-threaded, on 2 shared cores (load 13); the labelling
runs one process per core anyway, and in one process ``match_all_pairs`` spreads image pairs
over Python threads. The products are exact (integer-valued descriptors), so the thread
count never changes a result.

``limit(n)`` finds NumPy's OpenBLAS among the loaded libraries (``/proc/self/maps``) and
calls its ``openblas_set_num_threads`` (under whichever prefix and suffix the wheel gave
it), restoring the previous count on exit. Where there is no such library (another BLAS,
not Linux), it does nothing.
"""

from __future__ import annotations

import contextlib
import ctypes
import functools
import threading

__all__ = ["limit"]

_PREFIXES = ("scipy_openblas", "openblas")
_SUFFIXES = ("64_", "_64", "")
_lock = threading.Lock()
_depth = 0  # nested or concurrent limit() blocks: the outermost one restores
_previous = 0  # the count the outermost block found


@functools.cache
def _openblas() -> tuple | None:
    """(get, set) of the process's OpenBLAS thread count, or None."""
    import numpy  # noqa: F401  (loads NumPy's OpenBLAS)

    try:
        with open("/proc/self/maps") as f:
            paths = {line.split()[-1] for line in f if "openblas" in line.lower()}
    except OSError:
        return None
    for path in sorted(p for p in paths if ".so" in p):
        try:
            lib = ctypes.CDLL(path)
        except OSError:
            continue
        for prefix in _PREFIXES:
            for suffix in _SUFFIXES:
                get = getattr(lib, f"{prefix}_get_num_threads{suffix}", None)
                set_ = getattr(lib, f"{prefix}_set_num_threads{suffix}", None)
                if get is not None and set_ is not None:
                    get.restype = ctypes.c_int
                    set_.argtypes = [ctypes.c_int]
                    return get, set_
    return None


def threads() -> int | None:
    """OpenBLAS's thread count now (None: no OpenBLAS found)."""
    blas = _openblas()
    return None if blas is None else int(blas[0]())


@contextlib.contextmanager
def limit(n: int):
    """Run the block with OpenBLAS on ``n`` threads (process-wide), then restore the count."""
    global _depth, _previous
    blas = _openblas()
    if blas is None:
        yield
        return
    get, set_ = blas
    with _lock:
        _depth += 1
        if _depth == 1:
            _previous = int(get())
            set_(int(n))
    try:
        yield
    finally:
        with _lock:
            _depth -= 1
            if _depth == 0:
                set_(_previous)
