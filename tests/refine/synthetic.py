"""Small synthetic faces for the refine tests: a bumpy height field (a "face" with a nose and two cheeks)."""

import numpy as np


def bumpy_surface(n_side: int = 30, *, rng: np.random.Generator | None = None) -> np.ndarray:
    """(n_side^2, 3) points of z = f(x, y) on [-1, 1]^2 with three Gaussian bumps; jittered when rng is given."""
    u = np.linspace(-1.0, 1.0, n_side)
    x, y = np.meshgrid(u, u)
    x, y = x.ravel(), y.ravel()
    if rng is not None:
        x = x + rng.uniform(-0.2, 0.2, x.shape) * (u[1] - u[0])
        y = y + rng.uniform(-0.2, 0.2, y.shape) * (u[1] - u[0])
    z = 0.5 * np.exp(-(x**2 + y**2) / 0.1) + 0.25 * np.exp(-((x - 0.5) ** 2 + (y + 0.3) ** 2) / 0.08)
    z += 0.25 * np.exp(-((x + 0.5) ** 2 + (y + 0.3) ** 2) / 0.08)
    return np.stack([x, y, z], axis=1)


def smooth_warp(points: np.ndarray, amount: float) -> np.ndarray:
    """A known smooth non-rigid warp (mostly out of plane, some in plane), zero for amount = 0."""
    x, y, z = points.T
    dz = amount * 0.15 * np.sin(1.5 * x) * np.cos(1.2 * y)
    dx = amount * 0.05 * np.cos(1.3 * y)
    dy = amount * 0.04 * np.sin(1.1 * x)
    return points + np.stack([dx, dy, dz], axis=1)
