"""The one place for numba flags: every kernel is compiled with ``@njit(**NJIT)``."""

NJIT = dict(cache=True, nogil=True, fastmath=False, error_model="numpy")
