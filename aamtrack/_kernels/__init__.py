"""Compiled kernels (numba). Every kernel is private; public wrappers live next to the code that uses them."""

from ._flags import NJIT

__all__ = ["NJIT"]
