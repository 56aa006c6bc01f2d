"""Broad phase for particle-particle contact: a uniform grid, dense or hashed (Numba).

Each step, for the active particles with a radius (cell size >= the largest diameter):

1. ``bin_particles``: each particle's cell. *Dense* mode (the particles' bounding box holds at
   most ~4 cells per particle): the cell's linear index in that box, so neighbouring cells are
   neighbours in memory. *Hash* mode otherwise: the cell coordinates are packed into one key
   and hashed into ``table_size`` buckets (a power of two >= 2N); keys are compared on lookup.
2. ``counting_sort``: bucket counts, exclusive prefix sum, stable scatter (serial: the order,
   hence everything after it, is the same at any thread count). ``order`` lists the particles
   cell by cell.
3. ``gather``: positions, radii (and, for the solver, velocities, masses...) copied into cell
   order ("sorted space", position q holds particle order[q]): neighbours become neighbours in
   memory, which is what keeps a million-particle step in cache.
4. ``count_pairs`` / ``fill_pairs``: each sorted particle q looks at the 3^D cells around its
   own (dense mode: 3^(D-1) contiguous runs of 3 cells) and records the neighbours p > q within
   r_q + r_p + margin: counts first (parallel), an exclusive prefix sum, then each writes its
   own slice (parallel, write-disjoint). Pairs are in sorted space; ``scatter`` writes the
   solved data back to the particles.
5. ``color_pairs``: greedy edge colouring (serial, in pair order): no particle appears twice in
   one colour, so the solver can process a colour in parallel without races and the result
   does not depend on the thread count (Box2D's constraint graph colouring, applied to pairs).

Memory is preallocated by the caller; the pair buffer grows (amortised) when it overflows.

References
----------
- Teschner, M., Heidelberger, B., Mueller, M., Pomeranets, D. & Gross, M. (2003), "Optimized
  spatial hashing for collision detection of deformable objects", VMV: the hash function.
- Green, S. (2010), "Particle simulation using CUDA", NVIDIA whitepaper: the sorted uniform
  grid built with a counting sort, traversed in cell order.
- Catto, E. (2024), Box2D v3 ``constraint_graph.c``: colouring so that solver batches are
  write-disjoint.

Limitations
-----------
- One cell size for all particles (the largest diameter): very different radii make the small
  particles' neighbourhoods expensive.
- Hash mode clamps coordinates beyond +/- 2^20 cells from the origin.
- More than 63 colours (a particle with over ~32 contacts) puts the rest in a last colour that is
  solved serially.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from .._jit import serial_twin

OFFSET = 1 << 20
MAX_COLORS = 64  # colours 0..62 are parallel batches, colour 63 is the serial overflow
DENSE_CELLS_PER_PARTICLE = 4


@njit(cache=True)
def _cell(v, inv_cell):
    c = int(math.floor(v * inv_cell))
    return min(max(c, -OFFSET + 1), OFFSET - 2)


@njit(cache=True)
def _key(cx, cy, cz):
    return ((cx + OFFSET) << 42) | ((cy + OFFSET) << 21) | (cz + OFFSET)


@njit(cache=True)
def _bucket(cx, cy, cz, mask):
    h = (cx * 73856093) ^ (cy * 19349663) ^ (cz * 83492791)
    return h & mask


@njit(cache=True)
def _dense_cell(x, i, origin, inv_cell, dims):
    # cell coordinates inside the dense box (clamped: the box holds every particle)
    dim = x.shape[1]
    cx = min(max(int((x[i, 0] - origin[0]) * inv_cell), 0), dims[0] - 1)
    cy = min(max(int((x[i, 1] - origin[1]) * inv_cell), 0), dims[1] - 1)
    cz = min(max(int((x[i, 2] - origin[2]) * inv_cell), 0), dims[2] - 1) if dim == 3 else 0
    return cx, cy, cz


@njit(cache=True, parallel=True)
def bin_particles(x, radius, active, inv_cell, origin, dims, dense, mask, cell_key, bucket):
    """cell_key (N,) and bucket (N,) int64 of each particle; bucket = -1 when excluded.

    dense: bucket = cx + nx (cy + ny cz) in the box at ``origin`` with ``dims`` cells;
    hash: cell_key = packed absolute cell, bucket = its hash & mask."""
    n, dim = x.shape
    for i in prange(n):
        if not active[i] or radius[i] <= 0.0:
            bucket[i] = -1
            cell_key[i] = -1
            continue
        if dense:
            cx, cy, cz = _dense_cell(x, i, origin, inv_cell, dims)
            bucket[i] = cx + dims[0] * (cy + dims[1] * cz)
            cell_key[i] = bucket[i]
        else:
            cx = _cell(x[i, 0], inv_cell)
            cy = _cell(x[i, 1], inv_cell)
            cz = _cell(x[i, 2], inv_cell) if dim == 3 else 0
            cell_key[i] = _key(cx, cy, cz)
            bucket[i] = _bucket(cx, cy, cz, mask)


@njit(cache=True)
def counting_sort(bucket, nbuckets, bucket_start, order):
    """Stable counting sort of particle indices by bucket (excluded particles dropped).

    bucket_start (>= nbuckets + 1,): particles of bucket b are
    order[bucket_start[b]:bucket_start[b+1]]. Returns the number of particles sorted.
    """
    for b in range(nbuckets + 1):
        bucket_start[b] = 0
    n = bucket.shape[0]
    for i in range(n):
        b = bucket[i]
        if b >= 0:
            bucket_start[b + 1] += 1
    for b in range(1, nbuckets + 1):
        bucket_start[b] += bucket_start[b - 1]
    total = bucket_start[nbuckets]
    # scatter with a running cursor per bucket (reuse the prefix, shifted back afterwards)
    for i in range(n):
        b = bucket[i]
        if b >= 0:
            order[bucket_start[b]] = i
            bucket_start[b] += 1
    for b in range(nbuckets, 0, -1):
        bucket_start[b] = bucket_start[b - 1]
    bucket_start[0] = 0
    return total


@njit(cache=True, parallel=True)
def gather(order, nsorted, src, dst):
    """dst[q] = src[order[q]] for q < nsorted (rows of a 1-D or 2-D array): the particle data
    in cell order, so that neighbours are neighbours in memory."""
    for q in prange(nsorted):
        dst[q] = src[order[q]]


@njit(cache=True, parallel=True)
def scatter(order, nsorted, src, dst):
    """dst[order[q]] = src[q] for q < nsorted (the inverse of ``gather``; order is a permutation
    of the sorted particles, so the writes are disjoint)."""
    for q in prange(nsorted):
        dst[order[q]] = src[q]


@njit(cache=True)
def _neighbours(q, xs, rs, ks, inv_cell, origin, dims, dense, mask, bucket_start, margin, write, pair_i,
                pair_j, slot):
    # sorted space: particle q (data xs[q], rs[q]); the particles of bucket b are the positions
    # bucket_start[b]:bucket_start[b+1]. Count (write=False) or record the pairs (q, p), p > q.
    dim = xs.shape[1]
    zr = 1 if dim == 3 else 0
    count = 0
    if dense:
        cx, cy, cz = _dense_cell(xs, q, origin, inv_cell, dims)
        x_lo, x_hi = max(cx - 1, 0), min(cx + 1, dims[0] - 1)
        for dz in range(-zr, zr + 1):
            z = cz + dz
            if z < 0 or z >= dims[2]:
                continue
            for dy in range(-1, 2):
                y = cy + dy
                if y < 0 or y >= dims[1]:
                    continue
                # one contiguous run of 3 cells along x
                row = dims[0] * (y + dims[1] * z)
                for p in range(max(bucket_start[row + x_lo], q + 1), bucket_start[row + x_hi + 1]):
                    rx = xs[p, 0] - xs[q, 0]
                    ry = xs[p, 1] - xs[q, 1]
                    rz = (xs[p, 2] - xs[q, 2]) if dim == 3 else 0.0
                    reach = rs[q] + rs[p] + margin
                    if rx * rx + ry * ry + rz * rz < reach * reach:
                        if write:
                            pair_i[slot + count] = q
                            pair_j[slot + count] = p
                        count += 1
        return count
    cx = _cell(xs[q, 0], inv_cell)
    cy = _cell(xs[q, 1], inv_cell)
    cz = _cell(xs[q, 2], inv_cell) if dim == 3 else 0
    for dx in range(-1, 2):
        for dy in range(-1, 2):
            for dz in range(-zr, zr + 1):
                key = _key(cx + dx, cy + dy, cz + dz)
                b = _bucket(cx + dx, cy + dy, cz + dz, mask)
                for p in range(max(bucket_start[b], q + 1), bucket_start[b + 1]):
                    if ks[p] != key:
                        continue
                    rx = xs[p, 0] - xs[q, 0]
                    ry = xs[p, 1] - xs[q, 1]
                    rz = (xs[p, 2] - xs[q, 2]) if dim == 3 else 0.0
                    reach = rs[q] + rs[p] + margin
                    if rx * rx + ry * ry + rz * rz < reach * reach:
                        if write:
                            pair_i[slot + count] = q
                            pair_j[slot + count] = p
                        count += 1
    return count


@njit(cache=True, parallel=True)
def count_pairs(xs, rs, ks, inv_cell, origin, dims, dense, mask, bucket_start, nsorted, margin, pair_count):
    """pair_count[q] = number of neighbours p > q in contact range (sorted space)."""
    for q in prange(nsorted):
        pair_count[q] = _neighbours(q, xs, rs, ks, inv_cell, origin, dims, dense, mask, bucket_start, margin,
                                    False, pair_count, pair_count, 0)


@njit(cache=True)
def exclusive_scan(count, n, start):
    """start[q] = sum(count[:q]) for q <= n. Returns the total."""
    start[0] = 0
    for q in range(n):
        start[q + 1] = start[q] + count[q]
    return start[n]


@njit(cache=True, parallel=True)
def fill_pairs(xs, rs, ks, inv_cell, origin, dims, dense, mask, bucket_start, nsorted, margin, pair_start,
               pair_i, pair_j):
    """Write the pairs (q, p) of sorted particle q into pair_start[q]:pair_start[q+1]."""
    for q in prange(nsorted):
        if pair_start[q + 1] > pair_start[q]:
            _neighbours(q, xs, rs, ks, inv_cell, origin, dims, dense, mask, bucket_start, margin, True, pair_i,
                        pair_j, pair_start[q])


@njit(cache=True)
def color_pairs(pair_i, pair_j, npairs, used, pair_color, color_start, color_order, cursor):
    """Greedy edge colouring; pairs of colour c are color_order[color_start[c]:color_start[c+1]].

    used (N,) uint64 scratch (bit c set when the particle already has a pair of colour c);
    only the entries of particles in pairs are touched (and cleared again); cursor
    (MAX_COLORS,) int64 scratch. Returns the number of colours used.
    """
    for q in range(npairs):
        used[pair_i[q]] = 0
        used[pair_j[q]] = 0
    ncolors = 0
    color_start[:] = 0
    for q in range(npairs):
        taken = used[pair_i[q]] | used[pair_j[q]]
        c = 0
        while c < MAX_COLORS - 1 and (taken >> np.uint64(c)) & np.uint64(1):
            c += 1
        pair_color[q] = c
        if c < MAX_COLORS - 1:
            bit = np.uint64(1) << np.uint64(c)
            used[pair_i[q]] |= bit
            used[pair_j[q]] |= bit
        color_start[c + 1] += 1
        ncolors = max(ncolors, c + 1)
    for c in range(MAX_COLORS):
        color_start[c + 1] += color_start[c]
    for c in range(MAX_COLORS):
        cursor[c] = color_start[c]
    for q in range(npairs):
        c = pair_color[q]
        color_order[cursor[c]] = q
        cursor[c] += 1
    return ncolors


def table_size_for(n: int) -> int:
    """Hash table size: the power of two >= 2n (at least 64)."""
    return 1 << max(6, int(math.ceil(math.log2(max(2 * n, 2)))))


BOX_CHUNKS = 64


@njit(cache=True, parallel=True)
def bounding_box(x, partial, lo, hi):
    """lo, hi (3,) = the component-wise min and max of x (N, D); partial (BOX_CHUNKS, 6) scratch.
    Fixed chunks, so the same at any thread count (min and max are exact anyway)."""
    n, dim = x.shape
    chunk = (n + BOX_CHUNKS - 1) // BOX_CHUNKS
    for c in prange(BOX_CHUNKS):
        for d in range(3):
            partial[c, d] = np.inf
            partial[c, 3 + d] = -np.inf
        for i in range(c * chunk, min(n, (c + 1) * chunk)):
            for d in range(dim):
                v = x[i, d]
                if v < partial[c, d]:
                    partial[c, d] = v
                if v > partial[c, 3 + d]:
                    partial[c, 3 + d] = v
    for d in range(3):
        lo[d], hi[d] = 0.0, 0.0
    for d in range(dim):
        lo[d], hi[d] = np.inf, -np.inf
        for c in range(BOX_CHUNKS):
            lo[d] = min(lo[d], partial[c, d])
            hi[d] = max(hi[d], partial[c, 3 + d])


def grid_layout(x, cell, partial, lo, hi, dims, capacity) -> bool:
    """Fill lo (the dense grid's origin) and dims (cells per axis) for particles x (N, D) and
    cells of size ``cell``; False when the box needs more than ``capacity`` cells (hash mode).
    All arrays are preallocated scratch: (BOX_CHUNKS, 6), (3,), (3,), (3,) int64."""
    dim = x.shape[1]
    if x.shape[0] == 0:
        return False
    (bounding_box if x.shape[0] >= 16384 else bounding_box_serial)(x, partial, lo, hi)
    if not (np.isfinite(lo[:dim]).all() and np.isfinite(hi[:dim]).all()):
        return False
    cells = 1
    for d in range(3):
        extent = (hi[d] - lo[d]) / cell if d < dim else 0.0
        if extent > 2 ** 30:
            return False
        dims[d] = int(extent) + 1
        cells *= int(dims[d])
    return cells <= capacity


# serial twins for small systems (see _jit)
bin_particles_serial = serial_twin(bin_particles)
gather_serial = serial_twin(gather)
scatter_serial = serial_twin(scatter)
bounding_box_serial = serial_twin(bounding_box)
count_pairs_serial = serial_twin(count_pairs)
fill_pairs_serial = serial_twin(fill_pairs)
