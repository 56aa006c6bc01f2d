"""Implicit viscosity on a MAC grid, shared by `GridFluid` (smoke, single phase) and `LiquidFluid`
(free surface): backward Euler (I - nu dt Lap) u = u* per velocity component, solved by conjugate
gradients; unconditionally stable. GridFluid's scalar diffusion solves (I - kappa dt Lap) s = s*
with the same operator and solver on the cell scalars (their slots' ghost rules; solid cells are
zero-flux ``AIR`` neighbours, obstacles held at a temperature ``NO_SLIP`` with its value).

Each face node of a component has a kind (``FREE`` unknown, ``FIXED`` prescribed, ``NO_SLIP``
inside a no-slip obstacle, ``SLIP`` closed by a slip obstacle, ``AIR`` a liquid's face away from
the liquid). The domain sides enter through the ghost rules of `kernels.GridContext` (a
Dirichlet side is a no-slip wall, a Neumann side a slip wall). No-slip obstacles are Dirichlet
data at the surface's cut position between a fluid node and a solid node (symmetric ghost fluid,
Gibou, Fedkiw, Cheng and Kang 2002); the momentum each such link takes from the fluid is the
viscous force on the obstacle (`wall_shear_impulses`).

Free surface (liquids): a fluid node next to an ``AIR`` node sees a zero normal derivative of
its component across the surface (the ghost value equals the node's own value). This is the
traction-free condition of the separate-component Laplacian (the simplification of Batty and
Bridson 2008 that drops the cross-derivative terms of the stress): the tangential stress
du_t/dn = 0 is imposed, the part du_n/dt of the tangential stress and the normal viscous stress
2 mu du_n/dn are not (Batty and Bridson's variational stress form handles them). Limitation:
rotating and buckling viscous sheets and coils are damped wrongly near the surface (a rigidly
rotating blob slows down); a liquid at rest, shear parallel to the walls and flow past solids
are unaffected.

References
----------
- F. Gibou, R. Fedkiw, L.-T. Cheng and M. Kang, "A second-order-accurate symmetric
  discretization of the Poisson equation on irregular domains", J. Comput. Phys. 176, 2002.
- C. Batty and R. Bridson, "Accurate viscous free surfaces for buckling, coiling, and rotating
  liquids", SCA 2008 (traction-free surface; here in its separate-component simplification).
- R. Bridson, "Fluid Simulation for Computer Graphics", 2nd ed., 2015, ch. 10 (viscosity).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from .kernels import DIRICHLET, PERIODIC
from .obstacles import add_axis_impulse

# Node kinds of the implicit viscosity solve (one int8 per face node, per velocity component):
# Node kinds of the implicit viscosity solve (one int8 per face node, per velocity component):
FREE = 0        # an unknown
FIXED = 1       # prescribed at its own value (domain walls, inflow, faces closed by an obstacle)
NO_SLIP = 2     # inside a no-slip obstacle: a free neighbour sees the solid's velocity on the
#                 surface between them (ghost fluid, distance fraction theta from the node sdf)
SLIP = 3        # closed by a slip obstacle: prescribed along the component's own axis (the normal
#                 velocity), zero shear (Neumann) across the other axes
AIR = 4         # a liquid's face with no liquid cell on either side: across it the viscous stress
#                 is zero (a Neumann neighbour for every component: the traction-free surface of
#                 the separate-component Laplacian)
THETA_MIN = 0.02  # smallest distance fraction to a no-slip surface (keeps the system well conditioned)


@njit(cache=True, inline="always")
def _theta(sdf_c, sdf_n):
    """Fraction of the node spacing from a fluid node (sdf_c) to the zero crossing towards a solid
    node (sdf_n < 0), clamped to [THETA_MIN, 1]."""
    if sdf_c <= 0.0:
        return THETA_MIN
    t = sdf_c / (sdf_c - sdf_n)
    return THETA_MIN if t < THETA_MIN else (1.0 if t > 1.0 else t)


@njit(cache=True, inline="always")
def _neighbor(i, j, k, ax, sd, slot, shape, g):
    """Neighbour index of node (i, j, k) across side sd of axis ax: (ii, jj, kk, ghost) where ghost
    is -1 inside (or wrapped periodic), else the ghost kind of the domain side."""
    ii, jj, kk = i, j, k
    if ax == 0:
        ii = i + (2 * sd - 1)
    elif ax == 1:
        jj = j + (2 * sd - 1)
    else:
        kk = k + (2 * sd - 1)
    m = ii if ax == 0 else (jj if ax == 1 else kk)
    kind = g.ghost_kind[slot, ax, sd]
    # a periodic axis has n distinct nodes (a face array's node n duplicates node 0)
    size = g.n[ax] if kind == PERIODIC else shape[ax]
    if m < 0 or m >= size:
        if kind != PERIODIC:
            return ii, jj, kk, kind
        m2 = m % g.n[ax]
        if ax == 0:
            ii = m2
        elif ax == 1:
            jj = m2
        else:
            kk = m2
    return ii, jj, kk, -1


@njit(cache=True, parallel=True)
def helmholtz_apply(x, kind, sdf, slot, coef, g, out):
    """out = x - coef * Lap(x) on free nodes (other nodes: out = x), with the boundary data made
    homogeneous (it goes to `helmholtz_rhs`): a Dirichlet domain ghost contributes -2 x_c, a FIXED
    neighbour -x_c, a NO_SLIP neighbour -x_c / theta (the symmetric ghost-fluid discretisation of
    Gibou, Fedkiw, Cheng and Kang 2002), a SLIP neighbour -x_c along the slot's own axis and 0
    across, an AIR neighbour 0 (zero stress). coef = nu dt / h^2. Symmetric positive definite on the free nodes."""
    nx, ny, nz = x.shape
    nax = 3 if g.dim == 3 else 2
    # interior nodes whose neighbours are all inside the array and unwrapped (a periodic axis has
    # n distinct nodes): the fast path below reads them directly when all of them are FREE
    lim_x = g.n[0] if g.ghost_kind[slot, 0, 1] == PERIODIC else nx
    lim_y = g.n[1] if g.ghost_kind[slot, 1, 1] == PERIODIC else ny
    lim_z = g.n[2] if g.ghost_kind[slot, 2, 1] == PERIODIC else nz
    for i_ in prange(nx):
        i = np.int64(i_)
        for j in range(ny):
            for k in range(nz):
                if kind[i, j, k] != FREE:
                    out[i, j, k] = x[i, j, k]
                    continue
                c = x[i, j, k]
                if (1 <= i and i + 1 < lim_x and 1 <= j and j + 1 < lim_y
                        and (nax == 2 or (1 <= k and k + 1 < lim_z))
                        and kind[i - 1, j, k] == FREE and kind[i + 1, j, k] == FREE
                        and kind[i, j - 1, k] == FREE and kind[i, j + 1, k] == FREE
                        and (nax == 2 or (kind[i, j, k - 1] == FREE and kind[i, j, k + 1] == FREE))):
                    # the same sum in the same order as the general loop (bit-identical)
                    s = 0.0
                    s += x[i - 1, j, k] - c
                    s += x[i + 1, j, k] - c
                    s += x[i, j - 1, k] - c
                    s += x[i, j + 1, k] - c
                    if nax == 3:
                        s += x[i, j, k - 1] - c
                        s += x[i, j, k + 1] - c
                    out[i, j, k] = c - coef * s
                    continue
                s = 0.0
                for ax in range(nax):
                    for sd in range(2):
                        ii, jj, kk, gh = _neighbor(i, j, k, ax, sd, slot, x.shape, g)
                        if gh >= 0:
                            if gh == DIRICHLET:
                                s -= 2.0 * c
                            continue
                        nk = kind[ii, jj, kk]
                        if nk == FREE:
                            s += x[ii, jj, kk] - c
                        elif nk == FIXED:
                            s -= c
                        elif nk == NO_SLIP:
                            s -= c / _theta(sdf[i, j, k], sdf[ii, jj, kk])
                        elif nk == SLIP and ax == slot:
                            s -= c
                out[i, j, k] = c - coef * s


@njit(cache=True, parallel=True)
def helmholtz_rhs(x0, kind, sdf, wall, slot, coef, g, out):
    """Right-hand side of (I - coef Lap) x = x0 on free nodes: x0 plus the boundary data of
    Dirichlet domain ghosts, FIXED (and SLIP along the own axis) neighbours' values and, per NO_SLIP
    neighbour, u_wall / theta with u_wall the solid's velocity interpolated to the surface point
    ((1 - theta) wall_c + theta wall_n: exact for a rigid motion). Other nodes keep x0, NO_SLIP
    nodes take (in x0 too) the solid's velocity."""
    nx, ny, nz = x0.shape
    nax = 3 if g.dim == 3 else 2
    for i_ in prange(nx):
        i = np.int64(i_)
        for j in range(ny):
            for k in range(nz):
                kd = kind[i, j, k]
                if kd != FREE:
                    if kd == NO_SLIP:
                        x0[i, j, k] = wall[i, j, k]
                    out[i, j, k] = x0[i, j, k]
                    continue
                s = 0.0
                for ax in range(nax):
                    for sd in range(2):
                        ii, jj, kk, gh = _neighbor(i, j, k, ax, sd, slot, x0.shape, g)
                        if gh >= 0:
                            if gh == DIRICHLET:
                                s += 2.0 * g.ghost_value[slot, ax, sd]
                            continue
                        nk = kind[ii, jj, kk]
                        if nk == FIXED or (nk == SLIP and ax == slot):
                            s += x0[ii, jj, kk]
                        elif nk == NO_SLIP:
                            th = _theta(sdf[i, j, k], sdf[ii, jj, kk])
                            s += ((1.0 - th) * wall[i, j, k] + th * wall[ii, jj, kk]) / th
                out[i, j, k] = x0[i, j, k] + coef * s


@njit(cache=True)
def wall_shear_impulses(x, kind, sdf, wall, owner, slot, scale, g, ref, lin, ang):
    """Impulse of the viscous stress on no-slip obstacles after a viscous solve: for each link
    from a free node c to a NO_SLIP node n the solve moved momentum coef (u_wall - x_c) / theta
    per unit mass into the node's dual cell, so the obstacle `owner[n]` receives
    J = scale (x_c - u_wall) / theta along the slot's axis (scale = rho h^3 coef = rho nu dt h:
    the wall shear mu (x_c - u_wall) / (theta h) times the face area h^2 and dt), and the torque
    (x_wall - ref[o]) x J, x_wall = x_c + theta h e. Serial, in node order: deterministic."""
    nx, ny, nz = x.shape
    nax = 3 if g.dim == 3 else 2
    h = g.h
    for i in range(nx):
        for j in range(ny):
            for k in range(nz):
                if kind[i, j, k] != FREE:
                    continue
                for ax in range(nax):
                    for sd in range(2):
                        ii, jj, kk, gh = _neighbor(i, j, k, ax, sd, slot, x.shape, g)
                        if gh >= 0 or kind[ii, jj, kk] != NO_SLIP:
                            continue
                        o = owner[ii, jj, kk]
                        if o < 0:
                            continue
                        th = _theta(sdf[i, j, k], sdf[ii, jj, kk])
                        uw = (1.0 - th) * wall[i, j, k] + th * wall[ii, jj, kk]
                        J = scale * (x[i, j, k] - uw) / th
                        p0 = g.origin[0] + (i + (0.0 if slot == 0 else 0.5)) * h - ref[o, 0]
                        p1 = g.origin[1] + (j + (0.0 if slot == 1 else 0.5)) * h - ref[o, 1]
                        p2 = g.origin[2] + (k + (0.0 if slot == 2 else 0.5)) * h - ref[o, 2]
                        step = (2 * sd - 1) * th * h
                        if ax == 0:
                            p0 += step
                        elif ax == 1:
                            p1 += step
                        else:
                            p2 += step
                        add_axis_impulse(lin, ang, o, slot, J, p0, p1, p2)


def solve_component(kv, kk, x, kind, sdf, wall, slot, coef, g, cg, partial, rel_tol=1e-10,
                    max_iterations=1000):
    """Backward-Euler viscosity of one component in place: CG on (I - coef Lap) x = b from the
    current x (b = `helmholtz_rhs` of x). kv: this module's kernels (`kernels.KernelSet`), kk:
    `kernels`' (dot, axpy, xpby); cg: four scratch arrays shaped like x; partial: (>= x.shape[0],)
    scratch of the reductions. Returns the iteration count."""
    r, p, q, b = cg
    kv.helmholtz_rhs(x, kind, sdf, wall, slot, coef, g, b)
    kv.helmholtz_apply(x, kind, sdf, slot, coef, g, q)
    np.subtract(b, q, out=r)
    p[...] = r
    rr = kk.dot(r, r, partial)
    bnorm = math.sqrt(kk.dot(b, b, partial))
    tol = rel_tol * max(bnorm, 1e-300)
    xf, rf, pf, qf = x.reshape(-1), r.reshape(-1), p.reshape(-1), q.reshape(-1)
    it = 0
    for it in range(max_iterations):
        if math.sqrt(rr) <= tol:
            break
        kv.helmholtz_apply(p, kind, sdf, slot, coef, g, q)
        alpha = rr / kk.dot(p, q, partial)
        kk.axpy(alpha, pf, xf)
        kk.axpy(-alpha, qf, rf)
        rr_new = kk.dot(r, r, partial)
        kk.xpby(rf, rr_new / rr, pf)
        rr = rr_new
    return it


def obstacle_node_kinds(kind, sdf, owner, slip, edge):
    """Mark the face nodes inside obstacles (flat views; sdf < 0 at the node): NO_SLIP inside an
    obstacle whose flag in `slip` (one bool per obstacle: a bool array, or a sequence) is False,
    SLIP for FIXED (closed) nodes inside a slip obstacle; nodes with `edge` (domain sides whose
    value the side sets) are left alone. Returns whether any NO_SLIP node exists (a kernel:
    nothing allocated when `slip` is a bool array)."""
    if not isinstance(slip, np.ndarray) or slip.dtype != np.bool_:
        slip = np.asarray(slip, dtype=np.bool_).reshape(-1)
    return _obstacle_node_kinds(kind, sdf, owner, slip, edge)


@njit(cache=True)
def _obstacle_node_kinds(kind, sdf, owner, slip, edge):
    any_no_slip = False
    for m in range(kind.shape[0]):
        if edge[m] or not sdf[m] < 0.0:
            continue
        if not slip[owner[m]]:
            kind[m] = NO_SLIP
            any_no_slip = True
        elif kind[m] == FIXED:
            kind[m] = SLIP
    return any_no_slip


@njit(cache=True)
def fixed_where_closed(frac, kind):
    """kind = FIXED on closed faces (frac == 0), FREE elsewhere (flat views)."""
    for m in range(frac.shape[0]):
        kind[m] = FIXED if frac[m] == 0.0 else FREE


def slip_flags(slip, count, name):
    """One bool per obstacle from `slip` (a bool for all, or a sequence of `count` bools); a
    ValueError names `name` and the allowed values otherwise."""
    if isinstance(slip, (bool, np.bool_)):
        return [bool(slip)] * count
    try:
        flags = list(slip)
    except TypeError:
        raise ValueError(f"{name} must be True, False or one bool per obstacle; got {slip!r}") from None
    if len(flags) != count or not all(isinstance(x, (bool, np.bool_)) for x in flags):
        raise ValueError(f"{name} must be True, False or {count} bools (one per obstacle); got {slip!r}")
    return [bool(x) for x in flags]


@njit(cache=True)
def liquid_node_kinds(liquid, frac, axis, kind):
    """Kinds of a liquid's component-`axis` face nodes: FIXED where the face is closed (open
    fraction 0: domain walls, solids), FREE where a liquid cell lies on either side, AIR
    elsewhere (the traction-free surface: zero stress across it)."""
    nx, ny, nz = liquid.shape
    sx, sy, sz = kind.shape
    for i in range(sx):
        for j in range(sy):
            for k in range(sz):
                if frac[i, j, k] <= 0.0:
                    kind[i, j, k] = FIXED
                    continue
                i0, j0, k0 = i, j, k
                if axis == 0:
                    i0 = i - 1
                elif axis == 1:
                    j0 = j - 1
                else:
                    k0 = k - 1
                wet = False
                if i < nx and j < ny and k < nz and liquid[i, j, k]:
                    wet = True
                if i0 >= 0 and j0 >= 0 and k0 >= 0 and liquid[i0, j0, k0]:
                    wet = True
                kind[i, j, k] = FREE if wet else AIR


@njit(cache=True)
def mark_no_slip_valid(kind, valid):
    """valid |= (kind == NO_SLIP): nodes inside a no-slip solid hold its velocity after the solve
    (the liquid's velocity extrapolation keeps them)."""
    kf = kind.reshape(-1)
    vf = valid.reshape(-1)
    for m in range(kf.shape[0]):
        if kf[m] == NO_SLIP:
            vf[m] = True


@njit(cache=True)
def rigid_wall_velocity(wall, points, nodes, body, body_q, body_qd, axis, dim):
    """wall[nodes[m]] = component `axis` of v + w x (x - c) of rigid body body[m] at the face
    centre points[nodes[m]] ((M, dim); z = 0 in 2-D), from body_q (c) and body_qd (w, v): a
    dynamic body's surface velocity after the pressure solve changed its velocity."""
    wf = wall.reshape(-1)
    for m in range(nodes.shape[0]):
        n = nodes[m]
        b = body[m]
        rx = points[n, 0] - body_q[b, 0]
        ry = points[n, 1] - body_q[b, 1]
        rz = (points[n, 2] if dim == 3 else 0.0) - body_q[b, 2]
        wx, wy, wz = body_qd[b, 0], body_qd[b, 1], body_qd[b, 2]
        if axis == 0:
            wf[n] = body_qd[b, 3] + wy * rz - wz * ry
        elif axis == 1:
            wf[n] = body_qd[b, 4] + wz * rx - wx * rz
        else:
            wf[n] = body_qd[b, 5] + wx * ry - wy * rx
