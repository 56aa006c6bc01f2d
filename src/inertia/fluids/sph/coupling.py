"""Two-way coupling of an SPH fluid with the rigid core (``inertia.rigid.RigidWorld``).

Akinci, N., Ihmsen, M., Akinci, G., Solenthaler, B. & Teschner, M. (2012), "Versatile rigid-fluid
coupling for incompressible SPH", ACM TOG 31(4): rigid shapes are sampled with boundary particles
that move with their body; the fluid's pressure (and viscous) forces on them, summed per body, give
the force and torque of the fluid on the body, and the body pushes the fluid back through the
boundary particles' positions and velocities.

Here every row of the Model's shape table (``inertia.geometry.shapes``: sphere, box, capsule,
cylinder, convex hull, plane) is sampled at build time: the fluid lattice's points inside the solid
within one kernel support of its surface (a band, see ``SPHFluid``), from the shape's signed distance
in its local frame; boxes of moving bodies on a lattice fitted to their sides
(``fitted_box_lattice``: every face half a cell outside the outer layer). Shapes of dynamic and kinematic bodies are sampled on a lattice aligned with the
shape and stored in the body frame (centre of mass, principal axes); static shapes (body -1 or a
static body) on the fluid's world lattice. ``SPHFluid.advance(dt, rigid)`` poses the bands from
``rigid.state.body_q/body_qd``, runs fluid steps that cover dt, and pushes the bodies back with the
impulse sum_steps F dt (linear) and sum_steps T dt (angular, about the centre of mass) written into
``body_qd`` (``inertia.dynamics.particle_coupling.apply_body_impulses``: dv = J / m, dw = I_world^-1 L;
dynamic bodies only).

The force on a boundary particle is the reaction of the fluid's pressure acceleration on it, with the
boundary particle's own pressure k_b in the symmetric SPH sum m (k_i + k_b) (``SPHFluid(boundary_pressure=
...)``): "extrapolated" the Shepard average of the fluid pressures plus the wall-normal
body-force share (Adami, Hu & Adams 2012, "A generalized wall boundary condition for SPH", J. Comput.
Phys. 231; ``kernels.boundary_extrapolated_pressure`` / ``body_boundary_pressure_wrench``), "mirror"
(the DFSPH default; WCSPH defaults to "akinci") k_b = k_i (Akinci et al. 2012) plus the wall's
hydrostatic share g . (x_b - x_i) / rho_i
(``kernels.boundary_hydrostatic_kick`` / ``body_hydrostatic_wrench``; the full offset for a particle
under pressure: its wall-normal part alone lost the share in corners and on the slab bodies' periodic
faces; a particle without pressure takes only the wall-normal part). The normals n_b are the
unit gradients of the shapes' signed distances at the sample points (``sample_model``). With k_i alone (the earlier
form) a uniform pressure pushed particles into every wall, the solver inflated k there, and a held
submerged box felt 0.87 of rho0 g V; with both, 1.00 (``tests/fluids/sph/test_coupling.py``).

Limitations
- 3-D fluids only (the Model is 3-D); a 2-D scene is a thin 3-D fluid periodic across its depth.
- Triangle meshes and heightfields are not sampled (``ValueError``); convex hulls use the maximum of
  their face planes (exact inside, which is all the band needs).
- Several shapes of one body overlap where they touch: their bands are not merged (the overlap
  counts twice in the density near the joint).
- Explicit coupling: the rigid step integrates the fluid impulse of the previous world step
  (first-order splitting; light bodies need the fluid's viscosity/XSPH to settle). During the fluid
  sub-steps of one world step the bodies move with their velocity (poses extrapolated). (A free
  square box of density 0.5 rolling over is physics, not this: a square floats upright only for
  density ratios s < (3 - sqrt 3)/6 = 0.211 or s > 0.789, Delbourgo 1987, "The floating plank",
  Am. J. Phys. 55; the 0.4 m box of the tests at s = 0.5 has GM = KB + BM - KG = 0.1 + 0.067 - 0.2
  = -0.033 m. Whether free light bodies are also destabilised by the explicit coupling is open.)
- The wall's hydrostatic share uses gravity only, not the body's acceleration (Adami's g - a_w).
- Boundary normals (used by the "extrapolated" boundary pressure) are the gradients of the closed
  shape's signed distance: a body spanning a periodic axis (the 2-D slabs) gets normals towards its
  faces on that axis, which are not walls (its body-force share is then lost there).
"""

from __future__ import annotations

import numpy as np

from ...geometry import shapes as S

__all__ = ["shape_signed_distance", "sample_model", "quat_to_matrices", "fitted_box_lattice"]

SAMPLED_TYPES = (S.SPHERE, S.BOX, S.CAPSULE, S.CYLINDER, S.CONVEX_HULL, S.PLANE)


def quat_to_matrices(q):
    """(B, 4) unit quaternions (w, x, y, z) -> (B, 3, 3) rotation matrices."""
    q = np.asarray(q, float).reshape(-1, 4)
    w, x, y, z = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    r = np.empty((q.shape[0], 3, 3))
    r[:, 0, 0] = 1 - 2 * (y * y + z * z)
    r[:, 0, 1] = 2 * (x * y - w * z)
    r[:, 0, 2] = 2 * (x * z + w * y)
    r[:, 1, 0] = 2 * (x * y + w * z)
    r[:, 1, 1] = 1 - 2 * (x * x + z * z)
    r[:, 1, 2] = 2 * (y * z - w * x)
    r[:, 2, 0] = 2 * (x * z - w * y)
    r[:, 2, 1] = 2 * (y * z + w * x)
    r[:, 2, 2] = 1 - 2 * (x * x + y * y)
    return r


def _hull_planes(verts):
    from scipy.spatial import ConvexHull
    return ConvexHull(verts).equations  # (F, 4): n . p + d <= 0 inside


def shape_signed_distance(shape_type, params, p, verts=None):
    """Signed distance [m] of points p (M, 3) given in the shape's local frame (negative inside).
    Hulls: max over face planes (exact inside and along face normals)."""
    p = np.asarray(p, float)
    if shape_type == S.SPHERE:
        return np.linalg.norm(p, axis=1) - params[0]
    if shape_type == S.BOX:
        q = np.abs(p) - np.asarray(params[:3])
        outside = np.linalg.norm(np.maximum(q, 0.0), axis=1)
        return outside + np.minimum(q.max(axis=1), 0.0)
    if shape_type == S.CAPSULE:
        z = np.clip(p[:, 2], -params[1], params[1])
        d = p.copy()
        d[:, 2] -= z
        return np.linalg.norm(d, axis=1) - params[0]
    if shape_type == S.CYLINDER:
        q = np.stack([np.hypot(p[:, 0], p[:, 1]) - params[0], np.abs(p[:, 2]) - params[1]], axis=1)
        return np.linalg.norm(np.maximum(q, 0.0), axis=1) + np.minimum(q.max(axis=1), 0.0)
    if shape_type == S.CONVEX_HULL:
        eq = _hull_planes(verts)
        return (p @ eq[:, :3].T + eq[:, 3]).max(axis=1)
    if shape_type == S.PLANE:
        return p[:, 2].copy()
    raise ValueError(f"shape type {shape_type} ({_name(shape_type)}) cannot be sampled with boundary particles; "
                     f"sampled types: {[_name(t) for t in SAMPLED_TYPES]}")


def _name(code):
    for k, v in S.SHAPE_NAMES.items():
        if v == code:
            return k
    return str(code)


def _local_bounds(shape_type, params, verts):
    if shape_type == S.SPHERE:
        r = np.full(3, params[0])
    elif shape_type == S.BOX:
        r = np.asarray(params[:3], float)
    elif shape_type == S.CAPSULE:
        r = np.array([params[0], params[0], params[0] + params[1]])
    elif shape_type == S.CYLINDER:
        r = np.array([params[0], params[0], params[1]])
    elif shape_type == S.CONVEX_HULL:
        return verts.min(axis=0), verts.max(axis=0)
    else:
        return None
    return -r, r


def fitted_box_lattice(half, spacing):
    """Points of a box of half extents ``half`` (D,) on a lattice fitted to it: per axis
    n = max(1, round(2 half / spacing)) cells of size 2 half / n (within half a spacing of
    ``spacing``), points at the cell centres, so every face lies half a cell outside the outer
    layer, as a wall on the fluid's lattice does. On the plain lattice a box whose sides are not
    multiples of the spacing has its outer layer up to half a spacing off: the fluid then sees a
    box up to one spacing taller or shorter (a box of 9.6 spacings sampled as 10 floated 0.2
    spacings high)."""
    half = np.asarray(half, float)
    axes = []
    for h in half:
        n = max(1, int(round(2 * h / spacing)))
        axes.append(-h + (np.arange(n) + 0.5) * (2 * h / n))
    grids = np.meshgrid(*axes, indexing="ij")
    return np.ascontiguousarray(np.stack([g.ravel() for g in grids], axis=1))


def _transform(pose, p):
    """pose (7,) = position, quaternion (w, x, y, z): world = R p + t."""
    return p @ quat_to_matrices(pose[3:7])[0].T + pose[:3]


def _inverse_transform(pose, p):
    return (p - pose[:3]) @ quat_to_matrices(pose[3:7])[0]


def sample_model(model, body_q, spacing, support, lattice, world_lo, world_hi, world_origin):
    """Boundary bands of every shape row. Returns a list of (points (M, 3), body, local (M, 3),
    normal (M, 3)): body -1 with world points and normals for static geometry; the rigid body
    index with body-frame points (``local``) and normals and their world positions at ``body_q``
    for dynamic/kinematic bodies. The normal is the unit gradient of the signed distance.
    ``lattice(lo, hi, spacing, origin)`` makes lattice points (``fluid._lattice``)."""
    parts = []
    types = np.asarray(model.shape_type)
    for s in range(model.shape_count):
        st = int(types[s])
        if st not in SAMPLED_TYPES:
            raise ValueError(f"shape {s} is a {_name(st)}, which the SPH fluid cannot sample; sampled shape "
                             f"types: {[_name(t) for t in SAMPLED_TYPES]}")
        params = np.asarray(model.shape_params[s], float)
        verts = None
        if st == S.CONVEX_HULL:
            a = int(model.shape_vert_start[s])
            verts = np.asarray(model.geom_vertices[a:a + int(model.shape_vert_count[s])], float)
        body = int(model.shape_body[s])
        local_pose = np.asarray(model.shape_local_pose[s], float)
        moving = body >= 0 and int(model.body_type[body]) != S.STATIC
        if moving:
            lo, hi = _local_bounds(st, params, verts)
            if st == S.BOX:  # faces half a cell outside the outer layer
                pts = fitted_box_lattice(params[:3], spacing)
            else:
                # lattice symmetric about the shape's centre (a face at +-half keeps whole cells)
                n_cells = np.round((hi - lo) / spacing)
                origin = 0.5 * (lo + hi) - 0.5 * spacing * (n_cells % 2)
                pts = lattice(lo - spacing, hi + spacing, spacing, origin)
            sd = shape_signed_distance(st, params, pts, verts)
            keep = (sd < 0) & (sd >= -support)
            in_body = _transform(local_pose, pts[keep])
            world = _transform(np.asarray(body_q[body], float), in_body)
            normal = _surface_normal(st, params, pts[keep], verts, spacing) @ quat_to_matrices(local_pose[3:7])[0].T
            parts.append((world, body, in_body, normal))
        else:
            pose = local_pose if body < 0 else _compose(np.asarray(body_q[body], float), local_pose)
            pts = lattice(world_lo, world_hi, spacing, world_origin)
            local = _inverse_transform(pose, pts)
            sd = shape_signed_distance(st, params, local, verts)
            keep = (sd < 0) & (sd >= -support)
            normal = _surface_normal(st, params, local[keep], verts, spacing) @ quat_to_matrices(pose[3:7])[0].T
            parts.append((pts[keep], -1, np.zeros((int(keep.sum()), 3)), normal))
    return parts


def solid_cores(model):
    """(body, kind, cf, ci) per sphere, box, capsule, cylinder and convex hull row of a dynamic or
    kinematic body: the solids whose hollow core (deeper than the band) ``kernels.push_out_of_cores``
    keeps free of fluid, packed in the body frame as the collision layer's distance kinds
    (``inertia.collision.distance``): the first four as the shape table's rows pack them
    (``collision.shapes.BodyShape``), a hull as the CONTAINER of its face planes (inward normals
    -n, offsets d of n . p + d <= 0 inside; the hull's distance is minus the container's, exact
    inside). Plane rows (infinite) and meshes have no core."""
    from ...collision import distance as D
    from ...collision.shapes import BodyShape
    out = []
    types = np.asarray(model.shape_type)
    for s in range(model.shape_count):
        st = int(types[s])
        body = int(model.shape_body[s])
        if body < 0 or int(model.body_type[body]) == S.STATIC:
            continue
        if st in (S.SPHERE, S.BOX, S.CAPSULE, S.CYLINDER):
            row = BodyShape(model, s)
            out.append((body, int(row.kind), row._cf.copy(), np.zeros(1, np.int64)))
        elif st == S.CONVEX_HULL:
            a = int(model.shape_vert_start[s])
            verts = np.asarray(model.geom_vertices[a:a + int(model.shape_vert_count[s])], float)
            pose = np.asarray(model.shape_local_pose[s], float)
            eq = _hull_planes(verts)                       # shape frame: n . p + d <= 0 inside
            n_body = eq[:, :3] @ quat_to_matrices(pose[3:7])[0].T
            d_body = eq[:, 3] - n_body @ pose[:3]          # body frame: n' . x + d' <= 0 inside
            cf = np.concatenate([-n_body, d_body[:, None]], axis=1).reshape(-1)
            out.append((body, D.CONTAINER, cf, np.array([eq.shape[0]], np.int64)))
    return out


def _surface_normal(shape_type, params, p, verts, spacing):
    """(M, 3) unit gradient of the signed distance at p (shape frame; central differences of
    1e-3 spacing): the outward normal of the nearest surface point."""
    eps = 1e-3 * spacing
    g = np.empty((p.shape[0], 3))
    for d in range(3):
        e = np.zeros(3)
        e[d] = eps
        g[:, d] = shape_signed_distance(shape_type, params, p + e, verts) - shape_signed_distance(
            shape_type, params, p - e, verts)
    return g / np.maximum(np.linalg.norm(g, axis=1, keepdims=True), 1e-300)


def _compose(a, b):
    """Pose a * pose b (7-vectors)."""
    ra = quat_to_matrices(a[3:7])[0]
    out = np.empty(7)
    out[:3] = a[:3] + ra @ b[:3]
    w1, x1, y1, z1 = a[3:7]
    w2, x2, y2, z2 = b[3:7]
    out[3:7] = (w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2, w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2, w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2)
    return out
