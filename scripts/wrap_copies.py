"""The keys' error measures of the wrap, shared by scripts/bench_wrap.py and
blender_tests/test_wrap.py (plain numpy; the native module is passed in): the two simple copies
the carry is judged against (method, section 5) and the error against the same-topology result."""

import numpy as np


def moving_error(estimate, reference, diagonal):
    """Mean over shapes of the mean error on the vertices that move (more than 1e-3 of the
    diagonal in the reference), relative to the diagonal. `estimate`, `reference`: (K, N, 3)."""
    errors = []
    for est, ref in zip(estimate, reference):
        moving = np.linalg.norm(ref, axis=1) > 1e-3 * diagonal
        if moving.any():
            errors.append(np.linalg.norm(est[moving] - ref[moving], axis=1).mean() / diagonal)
    return float(np.mean(errors))


def nearest_vertex_copy(surface_positions, surface_deltas, points):
    """Each point takes the delta of the nearest surface vertex (the simplest binding, a
    baseline), brute force in chunks: (K, len(points), 3)."""
    nearest = np.empty(len(points), dtype=int)
    for start in range(0, len(points), 128):
        chunk = points[start:start + 128]
        nearest[start:start + 128] = np.argmin(((chunk[:, None, :] - surface_positions[None]) ** 2).sum(-1), axis=1)
    return surface_deltas[:, nearest]


def barycentric_copy(native, points, surface_positions, triangles, surface_deltas):
    """Each point takes the deltas at its closest point on the surface, mixed barycentrically
    (the plain barycentric copy; also how the same-topology result is sampled): (K, len(points), 3)."""
    triangle, barycentric, _ = native.bind_to_surface(
        np.ascontiguousarray(points, dtype=np.float32), np.ascontiguousarray(surface_positions, dtype=np.float32), triangles
    )
    return np.einsum("vc,kvcx->kvx", barycentric, surface_deltas[:, triangles[triangle]])
