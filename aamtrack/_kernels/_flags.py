"""The one place for numba flags: every kernel is compiled with ``@njit(**NJIT)``.

fastmath stays off. Measured 2026-11-21 (AMD EPYC, 2 logical CPUs, shared): ``fastmath={"reassoc", "contract"}``
made the search stage 5-10% faster (median 0.45-0.48 vs 0.50 ms per frame, 3D model, cap12 at 640x480), but
the results moved: on cap12 at 640x480 (8022 frames, ``--no-smooth``) the same frames were tracked and lost, while
the landmarks of 888 frames differed by more than 1e-4 px (at most 0.004 px), the tolerance asked of it.
"""

NJIT = dict(cache=True, nogil=True, fastmath=False, error_model="numpy")
