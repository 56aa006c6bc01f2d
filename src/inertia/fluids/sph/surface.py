"""Liquid surfaces from SPH particles: a smoothed colour field on a grid, then marching cubes.

Müller, M., Charypar, D. & Gross, M. (2003), "Particle-based fluid simulation for interactive
applications", SCA: the colour field c(g) = sum_j V_j W(g - x_j, h) (1 inside the fluid, 0 outside,
1/2 on a flat free surface), whose 1/2 level set is the liquid surface. Lorensen, W. E. & Cline,
H. E. (1987), "Marching cubes: a high resolution 3D surface construction algorithm", SIGGRAPH:
the triangle mesh of the level set (scikit-image's ``measure.marching_cubes``, Lewiner et al. 2003
variant; the optional dependency of this module, extra ``surface``).

    from inertia.fluids.sph import surface
    verts, faces = surface.reconstruct(fluid.x, spacing=fluid.spacing)      # (V, 3), (T, 3)
    surface.write_obj("water.obj", verts, faces); surface.write_ply_mesh("water.ply", verts, faces)

Limitations
- Isotropic kernel: thin sheets and single droplets (fewer particles than a kernel support) thin out
  or vanish (no anisotropic kernels as in Yu & Turk 2013); curvature pulls the 1/2 level inward by
  O(h^2 / R) on a drop of radius R.
- The splat is serial (deterministic) with a dense grid over the particles' bounds plus a margin:
  ~(extent / cell)^3 nodes, so it is a frame-export tool, not a per-step one.
- ``reconstruct`` (marching cubes) is 3-D; ``colour_field`` also splats 2-D particles, whose
  region c > 1/2 `inertia run` fills (``[render] fluid_surface``, `inertia.render.fluid_particles`).
- ``level_set`` turns c into phi = (1/2 - c) / |grad c| with one gradient for the frame (the median
  over the nodes near the surface): the zero level is exactly c = 1/2, the distance is first order.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from numba import njit

from .smoothing import kernel_id, kernel_norm, w_and_dwdr

__all__ = ["colour_field", "level_set", "reconstruct", "write_obj", "write_ply_mesh", "write_mesh_sequence"]


@njit(cache=True)
def _splat(x, volume, lo, cell, shape, kernel, h, sigma, out):
    """out[grid] += volume W(g - x_j) for every particle (serial: fixed order, deterministic)."""
    reach = 2.0 * h
    for j in range(x.shape[0]):
        i0 = max(0, int(np.floor((x[j, 0] - reach - lo[0]) / cell)))
        i1 = min(shape[0] - 1, int(np.ceil((x[j, 0] + reach - lo[0]) / cell)))
        j0 = max(0, int(np.floor((x[j, 1] - reach - lo[1]) / cell)))
        j1 = min(shape[1] - 1, int(np.ceil((x[j, 1] + reach - lo[1]) / cell)))
        k0 = max(0, int(np.floor((x[j, 2] - reach - lo[2]) / cell)))
        k1 = min(shape[2] - 1, int(np.ceil((x[j, 2] + reach - lo[2]) / cell)))
        for a in range(i0, i1 + 1):
            dx = lo[0] + a * cell - x[j, 0]
            for b in range(j0, j1 + 1):
                dy = lo[1] + b * cell - x[j, 1]
                for c in range(k0, k1 + 1):
                    dz = lo[2] + c * cell - x[j, 2]
                    r = np.sqrt(dx * dx + dy * dy + dz * dz)
                    if r < reach:
                        out[a, b, c] += volume * w_and_dwdr(kernel, r, h, sigma)[0]


@njit(cache=True)
def _splat_2d(x, volume, lo, cell, shape, kernel, h, sigma, out):
    """The 2-D ``_splat``: out[grid] += volume W(g - x_j) (serial, deterministic)."""
    reach = 2.0 * h
    for j in range(x.shape[0]):
        i0 = max(0, int(np.floor((x[j, 0] - reach - lo[0]) / cell)))
        i1 = min(shape[0] - 1, int(np.ceil((x[j, 0] + reach - lo[0]) / cell)))
        j0 = max(0, int(np.floor((x[j, 1] - reach - lo[1]) / cell)))
        j1 = min(shape[1] - 1, int(np.ceil((x[j, 1] + reach - lo[1]) / cell)))
        for a in range(i0, i1 + 1):
            dx = lo[0] + a * cell - x[j, 0]
            for b in range(j0, j1 + 1):
                dy = lo[1] + b * cell - x[j, 1]
                r = np.sqrt(dx * dx + dy * dy)
                if r < reach:
                    out[a, b] += volume * w_and_dwdr(kernel, r, h, sigma)[0]


def colour_field(x, spacing, *, smoothing_length=None, cell=None, kernel="cubic_spline", volume=None):
    """The colour field on a grid: returns (field (nx, ny[, nz]) float64, origin (D,) [m] of node 0,
    cell [m]). x: (N, 3) or (N, 2) positions. Defaults: h = spacing (cubic spline), cell = spacing / 2,
    V_j = spacing^D; the grid covers the particles' bounds plus one support and one cell."""
    x = np.ascontiguousarray(np.asarray(x, float))
    if x.ndim != 2 or x.shape[1] not in (2, 3):
        raise ValueError(f"x must be (N, 3) or (N, 2) particle positions; got shape {x.shape}")
    if x.shape[0] == 0:
        raise ValueError("x must hold at least one particle")
    dim = x.shape[1]
    if not spacing > 0:
        raise ValueError(f"spacing must be > 0; got {spacing!r}")
    h = float(spacing if smoothing_length is None else smoothing_length)
    cell = float(spacing / 2 if cell is None else cell)
    if not (h > 0 and cell > 0):
        raise ValueError("smoothing_length and cell must be > 0")
    volume = float(spacing ** dim if volume is None else volume)
    k = kernel_id(kernel)
    margin = 2 * h + cell
    lo = x.min(axis=0) - margin
    shape = np.ceil((x.max(axis=0) + margin - lo) / cell).astype(np.int64) + 1
    if int(np.prod(shape)) > 256 ** 3:
        raise ValueError(f"the surface grid would have {int(np.prod(shape))} nodes (> 256^3); raise cell "
                         f"(now {cell:g} m)")
    field = np.zeros(tuple(int(s) for s in shape))
    (_splat if dim == 3 else _splat_2d)(x, volume, lo, cell, shape, k, h, kernel_norm(k, dim, h), field)
    return field, lo, cell


def level_set(field, cell, level=0.5):
    """phi = (level - c) / g, negative inside the liquid: g is the median |grad c| over the nodes
    with |c - level| < 0.2 (one number for the field, so phi's zero set is c's level set exactly and
    phi is about the distance near it, in m). Returns phi (same shape, float64)."""
    c = np.asarray(field, np.float64)
    grads = np.gradient(c, float(cell))
    g2 = sum(gr * gr for gr in grads)
    near = np.abs(c - level) < 0.2
    g = float(np.sqrt(np.median(g2[near]))) if near.any() else 0.0
    if not g > 0:
        g = 1.0 / float(cell)
    return (level - c) / g


def reconstruct(x, spacing, *, level=0.5, smoothing_length=None, cell=None, kernel="cubic_spline"):
    """Triangle mesh of the liquid surface: vertices (V, 3) [m], faces (T, 3) int64 (outward normals
    by the right-hand rule). Needs scikit-image."""
    try:
        from skimage.measure import marching_cubes
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise ImportError("surface reconstruction needs scikit-image: pip install 'inertia[surface]'") from exc
    field, lo, c = colour_field(x, spacing, smoothing_length=smoothing_length, cell=cell, kernel=kernel)
    if not (field.max() > level):
        return np.zeros((0, 3)), np.zeros((0, 3), np.int64)
    verts, faces, _, _ = marching_cubes(field, level=level, spacing=(c, c, c))
    # skimage orients faces toward increasing field; flip so normals point out of the liquid
    return verts + lo, np.ascontiguousarray(faces[:, ::-1].astype(np.int64))


def write_obj(path, vertices, faces) -> Path:
    """Wavefront OBJ (text) of a triangle mesh."""
    path = Path(path)
    with open(path, "w") as f:
        f.write(f"# inertia SPH surface: {len(vertices)} vertices, {len(faces)} triangles\n")
        np.savetxt(f, np.asarray(vertices, float), fmt="v %.7g %.7g %.7g")
        np.savetxt(f, np.asarray(faces, np.int64) + 1, fmt="f %d %d %d")
    return path


def write_ply_mesh(path, vertices, faces) -> Path:
    """Binary little-endian PLY of a triangle mesh (float32 vertices, int32 face lists)."""
    path = Path(path)
    v = np.asarray(vertices, np.float32)
    f = np.asarray(faces, np.int32)
    header = (f"ply\nformat binary_little_endian 1.0\nelement vertex {len(v)}\nproperty float x\n"
              f"property float y\nproperty float z\nelement face {len(f)}\n"
              f"property list uchar int vertex_indices\nend_header\n").encode()
    rows = np.empty(len(f), dtype=[("n", "u1"), ("i", "<i4", (3,))])
    rows["n"] = 3
    rows["i"] = f
    tmp = path.with_suffix(path.suffix + ".tmp")
    with open(tmp, "wb") as out:
        out.write(header)
        out.write(v.astype("<f4").tobytes())
        out.write(rows.tobytes())
    os.replace(tmp, path)
    return path


def write_mesh_sequence(frames, directory, spacing, *, fmt="ply", pattern="surface_{frame:05d}", **kw):
    """One surface mesh file per frame: ``frames`` an iterable of (N, 3) particle positions (or of
    ``(x, active)`` pairs as in ``SPHFluid.frame_arrays``). ``fmt`` "ply" or "obj". Returns paths."""
    if fmt not in ("ply", "obj"):
        raise ValueError(f"fmt must be 'ply' or 'obj'; got {fmt!r}")
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    paths = []
    for i, frame in enumerate(frames):
        x = frame
        if isinstance(frame, tuple):
            x, active = frame
            x = np.asarray(x)[np.asarray(active, bool)]
        verts, faces = reconstruct(x, spacing, **kw)
        name = directory / (pattern.format(frame=i) + "." + fmt)
        paths.append(write_ply_mesh(name, verts, faces) if fmt == "ply" else write_obj(name, verts, faces))
    return paths
