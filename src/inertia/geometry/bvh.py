"""Bounding volume hierarchy over a static triangle mesh's triangles (built once, flat arrays).

Build (NumPy, once per mesh): top-down median split of the triangle centroids along the longest axis of
their bounds, leaves of at most ``LEAF_SIZE`` triangles; the triangles are reordered so every node covers a
contiguous range (Wald, Boulos and Shirley 2007 describe the top-down build; the median split is the
simplest of its heuristics). Query (Numba): boxes against the nodes with an explicit stack (the
caller's, ``bvh_query_box_stack``: the narrow phase keeps one per run, so a step allocates none).

Arrays (rows of one mesh; the shape table stores many meshes one after another)
- ``bounds (N, 6) float64`` m: node AABB (min xyz, max xyz) in the mesh's local frame.
- ``nodes (N, 3) int32``: internal node (left child, right child, 0); leaf (first triangle, count > 0 in the
  third column, -1). Child indices are relative to the mesh's first node; node 0 is the root.
- ``order (T,) int64``: the input triangle behind each reordered triangle.

Reference: Wald, I., Boulos, S. and Shirley, P. (2007). Ray tracing deformable scenes using dynamic
bounding volume hierarchies. ACM Transactions on Graphics 26(1).
Limitations: median split (no surface-area heuristic); static meshes only (no refit); query stack depth
``STACK_SIZE`` (64) bounds the tree depth, which the median split keeps at log2(T / LEAF_SIZE) + 1.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["LEAF_SIZE", "STACK_SIZE", "build_bvh", "bvh_query_box", "bvh_query_box_stack"]

LEAF_SIZE = 4
STACK_SIZE = 64


def build_bvh(tri_vertices: np.ndarray):
    """BVH of triangles ``tri_vertices (T, 3, 3)``; returns ``(order, bounds, nodes)`` (see module docs)."""
    tv = np.asarray(tri_vertices, dtype=np.float64)
    if tv.ndim != 3 or tv.shape[1:] != (3, 3) or len(tv) == 0:
        raise ValueError(f"tri_vertices must have shape (T >= 1, 3, 3); got {tv.shape}")
    lo_t = tv.min(axis=1)
    hi_t = tv.max(axis=1)
    cen = 0.5 * (lo_t + hi_t)
    order = np.arange(len(tv))
    bounds: list[np.ndarray] = []
    nodes: list[list[int]] = []

    def build(first, count):
        idx = order[first:first + count]
        me = len(nodes)
        bounds.append(np.concatenate([lo_t[idx].min(axis=0), hi_t[idx].max(axis=0)]))
        nodes.append([first, count, -1])
        if count <= LEAF_SIZE:
            nodes[me] = [first, -1, count]
            return me
        c = cen[idx]
        axis = int(np.argmax(c.max(axis=0) - c.min(axis=0)))
        srt = np.argsort(c[:, axis], kind="mergesort")
        order[first:first + count] = idx[srt]
        half = count // 2
        left = build(first, half)
        right = build(first + half, count - half)
        nodes[me] = [left, right, 0]
        return me

    # iterative depth is log2(T); Python recursion is fine for any mesh that fits in memory
    build(0, len(tv))
    return order.astype(np.int64), np.array(bounds), np.array(nodes, dtype=np.int32)


@njit(cache=True)
def bvh_query_box(bounds, nodes, root, lo, hi, out):
    """Triangles (reordered indices, relative to the mesh) of every leaf whose box overlaps [lo, hi];
    writes up to ``len(out)`` and returns the full count (a caller seeing count > len(out) grows and
    repeats). ``root`` is the mesh's first node row in ``bounds``/``nodes``. Makes its stack: inside a
    step use ``bvh_query_box_stack`` with a stack made once."""
    return bvh_query_box_stack(bounds, nodes, root, lo, hi, out, np.empty(STACK_SIZE, np.int32))


@njit(cache=True)
def bvh_query_box_stack(bounds, nodes, root, lo, hi, out, stack):
    """``bvh_query_box`` with the caller's traversal stack ``stack (>= STACK_SIZE,) int32`` (no allocation);
    ``lo``, ``hi``: three floats each (arrays or tuples)."""
    top = 0
    stack[0] = 0
    top = 1
    n = 0
    cap = out.shape[0]
    while top > 0:
        top -= 1
        k = root + stack[top]
        if (bounds[k, 0] > hi[0] or bounds[k, 1] > hi[1] or bounds[k, 2] > hi[2]
                or bounds[k, 3] < lo[0] or bounds[k, 4] < lo[1] or bounds[k, 5] < lo[2]):
            continue
        if nodes[k, 2] > 0:
            for t in range(nodes[k, 0], nodes[k, 0] + nodes[k, 2]):
                if n < cap:
                    out[n] = t
                n += 1
        else:
            stack[top] = nodes[k, 0]
            stack[top + 1] = nodes[k, 1]
            top += 2
    return n
