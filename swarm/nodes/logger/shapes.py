"""Body-frame points and EKF covariances as world-frame drawings, vectorized over rows."""

from __future__ import annotations

import numpy as np

_CIRCLE = np.stack([np.cos(np.linspace(0, 2 * np.pi, 25)), np.sin(np.linspace(0, 2 * np.pi, 25))], axis=1)


def to_world(pose: np.ndarray, body: np.ndarray) -> np.ndarray:
    """Body-frame points (x right, y ahead) of robots at ``pose`` (n x 3), world frame."""
    s, c = np.sin(pose[:, 2]), np.cos(pose[:, 2])
    x, y = body[:, 0], body[:, 1]
    return np.column_stack([pose[:, 0] + x * s + y * c, pose[:, 1] - x * c + y * s])


def ellipses(pose: np.ndarray, center: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """2-sigma ellipses of follower-frame covariances (xx, xy, yy), as world-frame
    polygons: n x 25 x 2."""
    c = np.stack([np.stack([cov[:, 0], cov[:, 1]], -1), np.stack([cov[:, 1], cov[:, 2]], -1)], -2)
    vals, vecs = np.linalg.eigh(c)  # n x 2, n x 2 x 2
    body = np.einsum("kj,nj,nij->nki", _CIRCLE, 2.0 * np.sqrt(np.maximum(vals, 0.0)), vecs)
    # Body-frame directions to world frame: x right -> (sin, -cos), y ahead -> (cos, sin).
    s, co = np.sin(pose[:, 2])[:, None], np.cos(pose[:, 2])[:, None]
    bx, by = body[..., 0], body[..., 1]
    return np.stack([bx * s + by * co, -bx * co + by * s], -1) + center[:, None, :]
