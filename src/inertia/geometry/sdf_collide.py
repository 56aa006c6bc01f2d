"""Convex shapes of dynamic bodies against baked signed-distance (SDF) rows of the shape table.

Storage: an ``SDF`` row (``inertia.geometry.shapes``, code 8) that was baked to a distance grid
(``inertia.colliders.SDF(..., bake=...)``, or a triangle mesh the rigid side cannot use, see
``inertia.model.with_colliders``) keeps the very ``GRID`` data the particle kernels read
(``inertia.collision.distance``, packed ``cf``/``ci``) in the Model columns ``sdf_grid_f (F,)``,
``sdf_grid_i (I,) int64`` from ``shape_sdf_start (S, 2) int64`` (float and integer offset; -1 for rows
without a grid). The grid lives in the collider's rest frame; ``shape_params[:3]`` of the row is the
rest-frame position of the row's own frame (the collider's reference point), so a point X in the row's
frame is looked up at ``X + shape_params[:3]``. ``geom_vertices`` holds the 8 corners of the field's
bounding box in the row's frame, which is all the broad phase needs.

Narrow phase (stage ``narrow_phase``, after the closed-form kernel, for pairs ``(convex shape, SDF)``):
the convex shape is represented by surface samples in its own frame (Guendelman, Bridson and Fedkiw
2003 test a body's sampled surface points against the other body's signed-distance grid):

============== ==========================================================================
sphere          its centre, radius r (sample index 0)
capsule         the two segment ends and the segment's midpoint, radius r (0, 1: ends, 2: mid)
box             8 corners, 12 edge midpoints, 6 face centres (index 0..26 of the 3x3x3 lattice
                {-h, 0, h}^3 without its centre)
cylinder        12 rim points per cap, then the two cap centres (26 samples)
convex hull     its vertices (a triangle mesh on a dynamic body is stored as hulls)
============== ==========================================================================

Each sample x (radius r) is carried into the SDF row's frame, its distance d(x) and unit gradient g(x)
are read from the compiled grid (``distance.sdf_in``, the particle kernels' trilinear evaluator); its
separation is d(x) - r. The manifold normal is minus the gradient at the deepest sample (A -> B, A the
convex shape, B the SDF: the gradient points out of the SDF solid); a sample whose own gradient turns by
less than 60 degrees from it (cos c >= 0.5) keeps its separation along that normal, (d - r) / c (the gap
closed moving along the normal before its own surface patch is touched, as the mesh path's crease rule)
and is kept when that is within the speculative distance. Points lie midway between the shape's surface
(x - r g) and the SDF surface. More than four points are reduced to four (deepest, farthest, largest
triangle, largest quad: ``narrowphase._reduce_and_emit``, Gregorius 2015). Feature key = sample index,
so warm starting matches points across steps.
Scratch: the samples' points, gradients, separations and keys live in the run's row of the narrow
phase's mesh bank (``narrowphase.MeshScratch``, rows for the scene's largest hull), so a step allocates
nothing.

References
- Guendelman, E., Bridson, R. and Fedkiw, R. (2003). Nonconvex rigid bodies with stacking. ACM TOG
  22(3) (SIGGRAPH): sampled surface points against signed-distance grids.
- Gregorius, D. (2015). Robust contact creation for physics simulations. GDC (four-point reduction).
- Bridson, Fedkiw and Anderson (2002): trilinearly interpolated distance grids (``collision.distance``).

Limitations
- Sampled, not exact: an SDF feature sharper than the sample spacing (a ridge or edge of the SDF solid
  under the middle of a large box face, between its samples) passes between the samples unseen; a box
  resting on a thin spike sinks onto it. Round sides (cylinders, capsules between their samples) are
  polygons of their samples.
- The field is only as good as its grid (``collision.distance``: within ``h sqrt(3)`` of the true
  distance; a plane or any linear field is exact). Outside the grid the distance is an upper bound and
  the broad phase stops at the grid's box: bodies beyond the baked ``bounds`` do not touch the SDF.
- One manifold, one normal per pair: a body wedged in a groove narrower than 120 degrees is held by its
  deepest wall's samples (the others leave the manifold) and partly by friction.
- Unbaked SDF colliders (a Python callable per query) have no grid: rigid bodies do not see them
  (``RigidWorld`` warns once naming them).
- Rows on static or kinematic bodies only (an SDF has no mass properties).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit, prange

from ..collision import distance as _d
from . import shapes as S
from ._tup import add, dot, madd, qconj, qmul, qrot, qrot_inv, scale, sub
from .narrowphase import (FAMILY_SDF, ManifoldOut, _RUNS, _reduce_and_emit, _set_normal, _speculative_distance,
                          _tangents, mesh_scratch_row, pair_family)

__all__ = ["SdfArrays", "sdf_arrays", "sample_count", "sample_point", "collide_sdf", "narrow_phase_sdf",
           "SAMPLES_BOX", "SAMPLES_CYLINDER", "CYLINDER_RIM"]

#: kind set of the distance evaluator: grids only (the other kinds' code is not compiled in)
_GRID_ONLY = _d.kinds_token([_d.GRID])
#: samples of the fixed-count shapes
SAMPLES_BOX = 26
CYLINDER_RIM = 12
SAMPLES_CYLINDER = 2 * CYLINDER_RIM + 2
#: a sample whose gradient turns farther than this (cosine) from the manifold normal is left out
MIN_COS = 0.5


class SdfArrays(NamedTuple):
    """Kernel bundle of the baked SDF rows (Model columns; read-only in a step)."""
    sdf_grid_f: np.ndarray       # (F,) float64: packed GRID floats of every baked row
    sdf_grid_i: np.ndarray       # (I,) int64: packed GRID integers
    shape_sdf_start: np.ndarray  # (S, 2) int64: float and integer offset of a row's grid, -1: none


def sdf_arrays(model) -> SdfArrays:
    """The `SdfArrays` of a Model (empty ones for models without SDF columns)."""
    f = getattr(model, "sdf_grid_f", None)
    if f is None:
        return SdfArrays(np.zeros(1), np.zeros(1, np.int64), np.full((model.shape_count, 2), -1, np.int64))
    return SdfArrays(model.sdf_grid_f, model.sdf_grid_i, model.shape_sdf_start)


@njit(cache=True)
def sample_count(ta, vert_count):
    """Number of surface samples of a convex shape of type ``ta`` (``vert_count``: a hull's vertices)."""
    if ta == S.SPHERE:
        return 1
    if ta == S.CAPSULE:
        return 3
    if ta == S.BOX:
        return SAMPLES_BOX
    if ta == S.CYLINDER:
        return SAMPLES_CYLINDER
    if ta == S.CONVEX_HULL:
        return vert_count
    return 0


@njit(cache=True)
def sample_point(ta, k, params, geom_vertices, vert_start):
    """Sample ``k`` of a convex shape in its own frame and the radius it carries (module docstring)."""
    if ta == S.SPHERE:
        return (0.0, 0.0, 0.0), params[0]
    if ta == S.CAPSULE:
        z = -params[1] if k == 0 else (params[1] if k == 1 else 0.0)
        return (0.0, 0.0, z), params[0]
    if ta == S.BOX:
        j = k if k < 13 else k + 1          # the 3x3x3 lattice {-1, 0, 1}^3 without its centre (13)
        return ((j // 9 - 1) * params[0], ((j // 3) % 3 - 1) * params[1], (j % 3 - 1) * params[2]), 0.0
    if ta == S.CYLINDER:
        if k < 2 * CYLINDER_RIM:
            ang = 2.0 * math.pi * (k % CYLINDER_RIM) / CYLINDER_RIM
            z = params[1] if k >= CYLINDER_RIM else -params[1]
            return (params[0] * math.cos(ang), params[0] * math.sin(ang), z), 0.0
        return (0.0, 0.0, params[1] if k == 2 * CYLINDER_RIM + 1 else -params[1]), 0.0
    v = geom_vertices[vert_start + k]
    return (v[0], v[1], v[2]), 0.0


@njit(cache=True)
def collide_sdf(out, i, ta, sa, sb, shapes, sdf, pose, spec, pts, seps, feats, grads):
    """Manifold ``i`` of convex shape ``sa`` (type ``ta``) against baked SDF row ``sb``; returns the
    point count. ``pts``, ``seps``, ``feats``, ``grads`` are scratch rows (at least the sample count)."""
    fo, io = sdf.shape_sdf_start[sb, 0], sdf.shape_sdf_start[sb, 1]
    if fo < 0:
        return 0                                          # unbaked: no grid to collide with
    cf, ci = sdf.sdf_grid_f, sdf.sdf_grid_i
    # A's pose in B's frame: X_B = p_rel + q_rel X_A
    pb = (pose[sb, 0], pose[sb, 1], pose[sb, 2])
    qb = (pose[sb, 3], pose[sb, 4], pose[sb, 5], pose[sb, 6])
    p_rel = qrot_inv(qb, (pose[sa, 0] - pb[0], pose[sa, 1] - pb[1], pose[sa, 2] - pb[2]))
    q_rel = qmul(qconj(qb), (pose[sa, 3], pose[sa, 4], pose[sa, 5], pose[sa, 6]))
    A = shapes.shape_params[sa]
    off = shapes.shape_params[sb]                        # rest-frame position of B's frame origin
    n_samples = sample_count(ta, shapes.shape_vert_count[sa])
    v0 = shapes.shape_vert_start[sa]
    geom = shapes.geom_vertices
    # 1. samples within reach: body-surface point (B frame), distance - radius, gradient
    cnt = 0
    deepest = 0
    for k in range(n_samples):
        lv, r = sample_point(ta, k, A, geom, v0)
        x = add(p_rel, qrot(q_rel, lv))
        d, gx, gy, gz = _d.sdf_in(_GRID_ONLY, _d.GRID, cf, fo, ci, io, x[0] + off[0], x[1] + off[1],
                                  x[2] + off[2])
        sep = d - r
        if sep > spec:
            continue
        pts[cnt, 0], pts[cnt, 1], pts[cnt, 2] = x[0] - r * gx, x[1] - r * gy, x[2] - r * gz
        grads[cnt, 0], grads[cnt, 1], grads[cnt, 2] = gx, gy, gz
        seps[cnt] = sep
        feats[cnt] = k
        if sep < seps[deepest]:
            deepest = cnt
        cnt += 1
    if cnt == 0:
        return 0
    # 2. one normal (the deepest sample's gradient); the others' gaps along it; points midway, world frame
    n = (grads[deepest, 0], grads[deepest, 1], grads[deepest, 2])
    kept = np.int64(0)  # int64 from the start (narrowphase: a literal 0 compiles callees twice)
    for k in range(cnt):
        g = (grads[k, 0], grads[k, 1], grads[k, 2])
        c = dot(g, n)
        if c < MIN_COS:
            continue
        sep = seps[k] / c
        if sep > spec:
            continue
        p = add(pb, qrot(qb, madd((pts[k, 0], pts[k, 1], pts[k, 2]), g, -0.5 * seps[k])))
        pts[kept, 0], pts[kept, 1], pts[kept, 2] = p
        seps[kept] = sep
        feats[kept] = feats[k]
        kept += 1
    normal = qrot(qb, scale(n, -1.0))
    _set_normal(out, i, normal)
    return _reduce_and_emit(out, i, pts, seps, feats, kept, normal)


@njit(cache=True)
def _narrow_range_sdf(lo, hi, pairs, shapes, sdf, pose, body_qd, body_bound_radius, dt, ca, bank, run):
    """The (convex, SDF) pairs of ``lo:hi`` (after ``narrow_phase_closed``): manifold, count, tangents; the
    samples in row ``run`` of the mesh bank (`narrowphase.MeshScratch`: ``pts``, ``seps``, ``feats``, and
    ``verts`` for the gradients)."""
    shape_body, shape_type, shape_margin = shapes.shape_body, shapes.shape_type, shapes.shape_margin
    shape_vert_count = shapes.shape_vert_count
    # rows for the largest sample count of the run: the bank's (sized for the scene's hulls), or, for a
    # bank made for fewer, rows of the run's own
    rows = SAMPLES_CYLINDER
    for i in range(lo, hi):
        sa = pairs[i, 0]
        if pair_family(shape_type[sa], shape_type[pairs[i, 1]]) == FAMILY_SDF:
            rows = max(rows, sample_count(shape_type[sa], shape_vert_count[sa]))
    scr = mesh_scratch_row(bank, run)
    if rows <= scr.pts.shape[0]:
        pts, grads, seps, feats = scr.pts, scr.verts, scr.seps, scr.feats
    else:
        pts, grads, seps, feats = np.empty((rows, 3)), np.empty((rows, 3)), np.empty(rows), np.empty(rows, np.int64)
    out = ManifoldOut(ca.contact_normal, ca.contact_point, ca.contact_separation, ca.contact_feature)
    contact_point_count, contact_normal, contact_tangent = (ca.contact_point_count, ca.contact_normal,
                                                            ca.contact_tangent)
    for i in range(lo, hi):
        sa, sb = pairs[i, 0], pairs[i, 1]
        ta = shape_type[sa]
        if pair_family(ta, shape_type[sb]) != FAMILY_SDF:
            continue
        spec = _speculative_distance(shape_body[sa], shape_body[sb], shape_margin[sa], shape_margin[sb], body_qd,
                                     body_bound_radius, dt)
        contact_point_count[i] = collide_sdf(out, i, ta, sa, sb, shapes, sdf, pose, spec, pts, seps, feats, grads)
        _tangents(i, contact_normal, contact_tangent)


@njit(cache=True, parallel=True)
def narrow_phase_sdf(pairs, npairs, shapes, sdf, pose, body_qd, body_bound_radius, dt, ca, mesh_bank):
    """The manifolds of the (convex shape, baked SDF) pairs, after ``narrow_phase_closed``; run ``ch`` works
    in row ``ch`` of ``mesh_bank`` (a `NarrowWork`'s ``mesh`` with a row per run), so a step allocates
    nothing."""
    nch = min(npairs, _RUNS)
    for ch in prange(nch):
        _narrow_range_sdf(npairs * ch // nch, npairs * (ch + 1) // nch, pairs, shapes, sdf, pose, body_qd,
                          body_bound_radius, dt, ca, mesh_bank, ch)
