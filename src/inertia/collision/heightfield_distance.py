"""Heightfield rows of the shape table as particles see them: the rigid side's triangles, closed below.

A HEIGHTFIELD row (``inertia.geometry.trimesh_collide``: grid points (x, y, height) in
``geom_vertices``, row ``i * ny + j``; cell (i, j) split into the triangles (v00, v10, v11) and
(v00, v11, v01)) is turned into a watertight triangle mesh: exactly those surface triangles (so
particles and rigid bodies see the same surface and the same face normals), four skirt walls down the
grid's border, and a bottom at ``min(height) - depth``. The closed mesh becomes a particle collider
through ``inertia.collision.mesh.Mesh`` (signed distance grid plus the exact segment-triangle
time-of-impact tests), so no new distance kind is needed in the particle kernels: the signed distance
is that of the solid under the surface, negative below it.

References
- Ericson, C. (2005). *Real-Time Collision Detection*, 5.1.5 (closest point on a triangle; used by the
  mesh collider's exact tests).
- Bridson, R. (2015). *Fluid Simulation for Computer Graphics*, ch. 4 (the baked signed distance).

Limitations
- The solid is the column under the grid, ``depth`` deep: a particle below the bottom or outside the
  grid's footprint sees the skirt walls, not an infinite terrain.
- The baked distance grid (``resolution`` cells along the longest side) smooths features smaller than
  a cell for particles larger than the mesh's ``exact_radius``; the exact triangle tests keep small
  particles on the true triangulated surface.
"""

from __future__ import annotations

import numpy as np

__all__ = ["heightfield_closed_mesh", "heightfield_height"]


def heightfield_closed_mesh(vertices, nx: int, ny: int, depth: float | None = None):
    """(vertices (V, 3), faces (F, 3) int64) of the closed solid under a heightfield's surface.

    ``vertices``: the row's (nx * ny, 3) grid points (x, y, height), index ``i * ny + j``; ``depth``:
    how far the bottom lies under the lowest point (default: the larger grid extent, at least 1 m).
    Faces are wound outward (counter-clockwise seen from outside)."""
    v = np.asarray(vertices, dtype=np.float64)
    nx, ny = int(nx), int(ny)
    if v.shape != (nx * ny, 3) or nx < 2 or ny < 2:
        raise ValueError(f"vertices must be (nx * ny, 3) = ({nx * ny}, 3) grid points with nx, ny >= 2; "
                         f"got {v.shape}")
    if depth is None:
        ext = max(np.ptp(v[:, 0]), np.ptp(v[:, 1]))
        depth = max(float(ext), 1.0)
    bottom = float(v[:, 2].min()) - float(depth)
    idx = np.arange(nx * ny).reshape(nx, ny)
    v00, v10 = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel()
    v11, v01 = idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    top = np.concatenate([np.stack([v00, v10, v11], 1), np.stack([v00, v11, v01], 1)])
    # the bottom copy of the grid's border ring: index nx * ny + (border vertex)
    below = v.copy()
    below[:, 2] = bottom
    verts = np.vstack([v, below])
    off = nx * ny
    faces = [top]

    def wall(ring):
        # ring: consecutive top vertices along the border, walked counter-clockwise seen from above
        # (the outside on the right); quads (a, b, b', a') split into two triangles
        a, b = ring[:-1], ring[1:]
        faces.append(np.stack([a, a + off, b + off], 1))
        faces.append(np.stack([a, b + off, b], 1))

    wall(idx[:, 0])                    # y min, walked along +x
    wall(idx[-1, :])                   # x max, along +y
    wall(idx[::-1, -1])                # y max, along -x
    wall(idx[0, ::-1])                 # x min, along -y
    # bottom: the grid's cells at the bottom level, wound downward
    faces.append(np.stack([v00 + off, v11 + off, v10 + off], 1))
    faces.append(np.stack([v00 + off, v01 + off, v11 + off], 1))
    return verts, np.concatenate(faces).astype(np.int64)


def heightfield_height(vertices, nx: int, ny: int, x, y):
    """Height of the triangulated surface (the rigid side's triangles) at points (x, y) inside the grid
    (NumPy; for tests and tools): the plane of the triangle of cell (i, j) holding the point."""
    v = np.asarray(vertices, dtype=np.float64)
    h = v[:, 2].reshape(nx, ny)
    x0, y0 = v[0, 0], v[0, 1]
    dx, dy = v[ny, 0] - x0, v[1, 1] - y0
    u, w = (np.asarray(x, float) - x0) / dx, (np.asarray(y, float) - y0) / dy
    i = np.clip(np.floor(u).astype(np.int64), 0, nx - 2)
    j = np.clip(np.floor(w).astype(np.int64), 0, ny - 2)
    s, t = u - i, w - j
    h00, h10, h11, h01 = h[i, j], h[i + 1, j], h[i + 1, j + 1], h[i, j + 1]
    # (v00, v10, v11) holds s >= t; (v00, v11, v01) holds s < t
    lower = h00 + s * (h10 - h00) + t * (h11 - h10)
    upper = h00 + t * (h01 - h00) + s * (h11 - h01)
    return np.where(s >= t, lower, upper)
