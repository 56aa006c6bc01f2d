"""Neighbour search for SPH: a dense counting-sort grid over the fluid domain, gather lists.

Each step (``SPHFluid._neighbours``):

1. ``bin_cells``: the cell of every active fluid particle in a dense grid over the domain, cells
   at least half a kernel support wide (``REACH`` = 2 cells per support; on a periodic axis the
   cell is ``L / floor(2 L / support)`` so that the cells tile the period). A fluid particle
   more than one support outside the domain on a non-periodic axis gets cell ``ESCAPED`` (-2),
   one inside an outflow box ``OUTFLOW`` (-1); both are dropped by the sort (closer ones, e.g.
   pressed into a wall's band, are clamped into the edge cells, as every boundary particle is).
   ``count_escaped`` counts the former: ``SPHFluid`` treats a large share of the fluid leaving
   through the domain bounds in one step as a blow-up.
2. ``inertia.collision.broadphase.counting_sort`` (reused: serial, stable, so the order is the
   same at any thread count) and ``broadphase.gather``: the fluid arrays are *reordered* into
   cell order and stay in that order ("sorted space"): neighbours become neighbours in memory.
   ``SPHFluid.particle_id`` follows the particles through the reordering.
3. ``fill_strided`` / ``exclusive_scan`` / ``compact`` (one distance pass writing the neighbour
   indices into fixed-stride rows, then ``compact`` evaluates W and grad W of each pair into
   CSR; ``count_neighbours`` / ``fill_neighbours`` when a row overflows its stride, which then
   grows): every particle i records *all*
   its neighbours j (fluid-fluid, excluding itself) and b (fluid-boundary) within the support,
   in CSR form, with the kernel value ``W_ij`` and gradient ``grad W_ij`` of each pair. Each
   particle writes only its own slice, so both passes are parallel and write-disjoint; every
   later SPH pass is a gather over these lists (the solver iterates ~10-40 times per step over
   the same pairs, so the kernel is evaluated once per pair and step). The 5 cells of a row of
   the 5 x 5 (x 5) block around a particle are consecutive in the sorted arrays and are walked as
   one particle range.

Why not the collision layer's pair list: ``broadphase.count_pairs`` records each pair once
(p > q) for a coloured, scatter-style contact solver; SPH sums over the full neighbourhood of
every particle many times per step, which a per-particle list reads without colouring or
atomics. The binning differs too (a fixed domain grid with periodic wrap instead of the
particles' bounding box or a hash).

References
----------
- Green, S. (2010), "Particle simulation using CUDA", NVIDIA whitepaper: sorted uniform grid.
- Ihmsen, M., Akinci, N., Becker, M. & Teschner, M. (2011), "A parallel SPH implementation on
  multi-core CPUs", Computer Graphics Forum 30(1): cell-ordered particle storage, neighbour
  lists reused by the pressure iterations.

Limitations
-----------
- The grid covers the (fixed) domain box densely: a domain much larger than the fluid wastes
  memory on empty cells (``dims`` product is capped, see ``SPHFluid``).
- Periodic axes need a period of at least three kernel supports (six cells).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit, prange

from .smoothing import kernel_norm, w_and_dwdr


# Cells per kernel support: cells at least support / REACH wide, blocks of 2 REACH + 1 cells per
# axis around a particle. REACH = 2 (cells of h) scans 25 h^2 around a 2D particle instead of
# the 36 h^2 of 3 x 3 cells of 2h (125 h^3 instead of 216 h^3 in 3D) for the pi 4 h^2 (33.5 h^3)
# that hold its neighbours.
REACH = 2
# bin_cells' marks for dropped rows (the counting sort drops every negative cell)
OUTFLOW = -1   # inside an outflow box, or an inactive slot (i >= n)
ESCAPED = -2   # more than ``margin`` outside the domain on a non-periodic axis


class Grid(NamedTuple):
    """The dense cell grid over the domain (built once by ``SPHFluid``)."""
    lo: np.ndarray        # (3,) float64 [m] domain lower corner (0 on unused axes)
    length: np.ndarray    # (3,) float64 [m] domain extents (1 on unused axes)
    inv_cell: np.ndarray  # (3,) float64 [1/m] cells per metre on each axis
    dims: np.ndarray      # (3,) int64 cells per axis (1 on the unused z axis in 2D)
    periodic: np.ndarray  # (3,) bool: the axis wraps around


@njit(cache=True, inline="always")
def _cell_coord(v, d, grid, margin):
    # cell index on axis d; outside the domain: clamped into the edge cell when within margin
    # [m] of it, else -1
    c = int(np.floor((v - grid.lo[d]) * grid.inv_cell[d]))
    n = grid.dims[d]
    if grid.periodic[d]:
        return c % n
    if c < 0 or c >= n:
        if v < grid.lo[d] - margin or v > grid.lo[d] + grid.length[d] + margin:
            return -1
        return min(max(c, 0), n - 1)
    return c


@njit(cache=True, parallel=True)
def bin_cells(x, n, grid, margin, outflow_lo, outflow_hi, cell_of):
    """cell_of[i] = linear cell of particle i < n: ``OUTFLOW`` (-1) inside any outflow box
    [outflow_lo[k], outflow_hi[k]) (K, 3) and for i >= n (inactive slots), ``ESCAPED`` (-2)
    beyond ``margin`` [m] outside the domain (particles within it are clamped into the edge
    cells)."""
    dim = x.shape[1]
    for i in prange(cell_of.shape[0]):
        if i >= n:
            cell_of[i] = OUTFLOW
            continue
        drop = False
        for k in range(outflow_lo.shape[0]):
            inside = True
            for d in range(dim):
                if x[i, d] < outflow_lo[k, d] or x[i, d] >= outflow_hi[k, d]:
                    inside = False
            if inside:
                drop = True
        if drop:
            cell_of[i] = OUTFLOW
            continue
        cx = _cell_coord(x[i, 0], 0, grid, margin)
        cy = _cell_coord(x[i, 1], 1, grid, margin)
        cz = _cell_coord(x[i, 2], 2, grid, margin) if dim == 3 else 0
        if cx < 0 or cy < 0 or cz < 0:
            cell_of[i] = ESCAPED
        else:
            cell_of[i] = cx + grid.dims[0] * (cy + grid.dims[1] * cz)


@njit(cache=True)
def count_escaped(cell_of, n):
    """Number of rows i < n that ``bin_cells`` marked ``ESCAPED`` (serial: one pass over ints,
    run only in steps that dropped particles)."""
    count = 0
    for i in range(n):
        if cell_of[i] == ESCAPED:
            count += 1
    return count


@njit(cache=True, inline="always")
def _min_image(r, d, grid):
    if grid.periodic[d]:
        L = grid.length[d]
        return r - L * np.floor(r / L + 0.5)
    return r


@njit(cache=True, inline="always")
def _separation(x0, x1, x2, xt, j, wrap, grid, dim):
    """x_i - x_j for x_i = (x0, x1, x2) and row j of xt, by the minimum image on periodic axes when
    ``wrap`` (any axis periodic); z is 0 in 2-D."""
    if wrap:
        rx = _min_image(x0 - xt[j, 0], 0, grid)
        ry = _min_image(x1 - xt[j, 1], 1, grid)
        rz = _min_image(x2 - xt[j, 2], 2, grid) if dim == 3 else 0.0
    else:
        rx = x0 - xt[j, 0]
        ry = x1 - xt[j, 1]
        rz = x2 - xt[j, 2] if dim == 3 else 0.0
    return rx, ry, rz


@njit(cache=True, inline="always")
def _store_pair(k, rx, ry, rz, r2, kernel, h, sigma, w_out, g_out):
    # W and grad_i W of the pair at displacement (rx, ry, rz) = x_i - x_j, |.|^2 = r2, into row k
    r = np.sqrt(r2)
    w, dw = w_and_dwdr(kernel, r, h, sigma)
    w_out[k] = w
    f = dw / r if r > 0.0 else 0.0
    g_out[k, 0] = f * rx
    g_out[k, 1] = f * ry
    if g_out.shape[1] == 3:
        g_out[k, 2] = f * rz


@njit(cache=True, inline="always")
def _row_segments(cx, n, periodic):
    # the cells cx-REACH .. cx+REACH of one row as at most 2 ranges [a, b) of consecutive cells:
    # one range unless the row wraps around a periodic axis (then in the order cx-REACH, ..,
    # cx+REACH too)
    a0 = cx - REACH
    b0 = cx + REACH + 1
    if not periodic:
        return max(a0, 0), min(b0, n), 0, 0
    if a0 >= 0 and b0 <= n:
        return a0, b0, 0, 0
    if a0 < 0:  # cells n+a0 .. n-1 | 0 .. b0-1
        return n + a0, n, 0, b0
    return a0, n, 0, b0 - n  # cells a0 .. n-1 | 0 .. b0-n-1


@njit(cache=True, inline="always")
def _visit(i, x0, x1, x2, xt, cell_start, grid, kernel, h, sigma, exclude_self, write, slot, limit, nbr, w_out, g_out,
           wrap):
    # gather the particles of set t within the support of point xi (write 0: count only; 1: their
    # indices into nbr[slot..], at most limit; 2: also W and grad W); returns the full count. The
    # 2 REACH + 1 rows ((2 REACH + 1)^2 in 3D) of the block of cells around xi are walked as
    # contiguous particle ranges (the cells of a row are consecutive in the sorted arrays), in the
    # order cell by cell, particle by particle within a cell; wrap: any periodic axis
    # (minimum-image displacements), else plain differences.
    dim = xt.shape[1]
    support2 = 4.0 * h * h
    zr = REACH if dim == 3 else 0
    nx = grid.dims[0]
    cx = min(max(int(np.floor((x0 - grid.lo[0]) * grid.inv_cell[0])), -1), nx)
    cy = min(max(int(np.floor((x1 - grid.lo[1]) * grid.inv_cell[1])), -1), grid.dims[1])
    cz = min(max(int(np.floor((x2 - grid.lo[2]) * grid.inv_cell[2])), -1), grid.dims[2]) if dim == 3 else 0
    a1, b1, a2, b2 = _row_segments(cx, nx, grid.periodic[0])
    count = 0
    for dz in range(-zr, zr + 1):
        z = cz + dz
        if grid.periodic[2]:
            z %= grid.dims[2]
        elif z < 0 or z >= grid.dims[2]:
            continue
        for dy in range(-REACH, REACH + 1):
            y = cy + dy
            if grid.periodic[1]:
                y %= grid.dims[1]
            elif y < 0 or y >= grid.dims[1]:
                continue
            row = nx * (y + grid.dims[1] * z)
            for seg in range(2):
                a = a1 if seg == 0 else a2
                b = b1 if seg == 0 else b2
                if a >= b:
                    continue
                for j in range(cell_start[row + a], cell_start[row + b]):
                    if exclude_self and j == i:
                        continue
                    rx, ry, rz = _separation(x0, x1, x2, xt, j, wrap, grid, dim)
                    r2 = rx * rx + ry * ry + rz * rz
                    if r2 >= support2:
                        continue
                    if write > 0 and count < limit:
                        k = slot + count
                        nbr[k] = j
                        if write == 2:
                            _store_pair(k, rx, ry, rz, r2, kernel, h, sigma, w_out, g_out)
                    count += 1
    return count


@njit(cache=True, parallel=True)
def count_neighbours(x, n, xt, cell_start, grid, kernel, h, exclude_self, count):
    """count[i] = number of particles of set t (positions xt, cell ranges cell_start) within
    the support 2h of fluid particle i < n."""
    dim = x.shape[1]
    sigma = kernel_norm(kernel, dim, h)
    wrap = grid.periodic[0] or grid.periodic[1] or grid.periodic[2]
    dummy_i = np.zeros(1, np.int32)
    dummy_w = np.zeros(1)
    dummy_g = np.zeros((1, dim))
    for i in prange(n):
        x2 = x[i, 2] if dim == 3 else 0.0
        count[i] = _visit(i, x[i, 0], x[i, 1], x2, xt, cell_start, grid, kernel, h, sigma, exclude_self, 0, 0, 0,
                          dummy_i, dummy_w, dummy_g, wrap)


@njit(cache=True, parallel=True)
def fill_neighbours(x, n, xt, cell_start, grid, kernel, h, exclude_self, start, nbr, w_out, g_out):
    """Write the neighbours of fluid particle i into start[i]:start[i+1] of nbr (index in set t),
    w_out (W_ij) and g_out (grad_i W_ij, (M, D))."""
    dim = x.shape[1]
    sigma = kernel_norm(kernel, dim, h)
    wrap = grid.periodic[0] or grid.periodic[1] or grid.periodic[2]
    for i in prange(n):
        x2 = x[i, 2] if dim == 3 else 0.0
        _visit(i, x[i, 0], x[i, 1], x2, xt, cell_start, grid, kernel, h, sigma, exclude_self, 2, start[i],
               start[i + 1] - start[i], nbr, w_out, g_out, wrap)


@njit(cache=True, parallel=True)
def fill_strided(x, n, xt, cell_start, grid, h, exclude_self, stride, count, nbr, no_w, no_g):
    """One search pass instead of count + fill: the neighbour indices of particle i go to rows
    i * stride .. of the scratch nbr (at most ``stride``), count[i] gets the full count (a count
    above stride means the rows are incomplete: the caller falls back to fill_neighbours). The
    kernel is evaluated by ``compact`` (the search pass writes 4 bytes per pair, not 28). no_w
    (1,) and no_g (1, D) float placeholders for the W / grad W outputs this pass does not write
    (the caller's, so that the kernel allocates nothing)."""
    dim = x.shape[1]
    wrap = grid.periodic[0] or grid.periodic[1] or grid.periodic[2]
    for i in prange(n):
        x2 = x[i, 2] if dim == 3 else 0.0
        count[i] = _visit(i, x[i, 0], x[i, 1], x2, xt, cell_start, grid, 0, h, 0.0, exclude_self, 1,
                          i * stride, stride, nbr, no_w, no_g, wrap)


@njit(cache=True, parallel=True)
def compact(x, n, xt, grid, kernel, h, stride, start, nbr_s, nbr, w_out, g_out):
    """The CSR lists (start from exclusive_scan) from the strided indices of fill_strided, with
    W_ij and grad_i W_ij evaluated here: the same lists, values and order as count_neighbours +
    fill_neighbours (the same displacement arithmetic)."""
    dim = x.shape[1]
    sigma = kernel_norm(kernel, dim, h)
    wrap = grid.periodic[0] or grid.periodic[1] or grid.periodic[2]
    for i in prange(n):
        a = start[i]
        c = start[i + 1] - a
        b = i * stride
        x0 = x[i, 0]
        x1 = x[i, 1]
        x2 = x[i, 2] if dim == 3 else 0.0
        for k in range(c):
            j = nbr_s[b + k]
            rx, ry, rz = _separation(x0, x1, x2, xt, j, wrap, grid, dim)
            nbr[a + k] = j
            _store_pair(a + k, rx, ry, rz, rx * rx + ry * ry + rz * rz, kernel, h, sigma, w_out, g_out)


@njit(cache=True)
def exclusive_scan(count, n, start):
    """start[i] = sum(count[:i]) for i <= n; returns the total."""
    start[0] = 0
    for i in range(n):
        start[i + 1] = start[i] + count[i]
    return start[n]
