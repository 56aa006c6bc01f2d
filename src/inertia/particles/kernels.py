"""Numba kernels for particle systems: force accumulation, gathers and fused steps.

Arrays: x, v, f are (N, D) float64; inv_mass is (N,) with 0 for pinned or inactive particles.
Forces add into f (the accumulator cleared at the start of each evaluation). Spring forces are
gathered per particle over a CSR incidence list (`incident_start`, `incident_other`,
`incident_spring`), so every particle's sum is written by one thread in a fixed order: results are
bit-identical at any Numba thread count, and f_i = -f_j holds exactly for each spring.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from .._jit import parallel_kernel


# --- fused path for per-particle affine forces: f = m g + F - k v -------------------------------

@parallel_kernel
def affine_acceleration(v, inv_mass, gravity, force, damping, out):
    """out_i = g + (F - k v_i) / m_i for free particles, 0 for pinned ones."""
    n, d = v.shape
    for i in prange(n):
        w = inv_mass[i]
        if w == 0.0:
            for c in range(d):
                out[i, c] = 0.0
        else:
            for c in range(d):
                out[i, c] = gravity[c] + (force[c] - damping * v[i, c]) * w


@parallel_kernel
def affine_derivative(v, inv_mass, gravity, force, damping, out_x, out_v):
    """dy/dt = [v, a] for affine forces, in one pass."""
    n, d = v.shape
    for i in prange(n):
        w = inv_mass[i]
        for c in range(d):
            vc = v[i, c]
            out_x[i, c] = vc
            out_v[i, c] = 0.0 if w == 0.0 else gravity[c] + (force[c] - damping * vc) * w


@parallel_kernel
def affine_kick_drift(x, v, inv_mass, gravity, force, damping, h):
    """Semi-implicit Euler for affine forces in one pass: reads x, v, 1/m; writes x, v.

    Returns True when every value of the new state is finite (pinned and inactive particles,
    which it does not move, included): the divergence check, folded into the same pass as
    sum(value * 0), which is 0 or NaN as soon as one value is NaN or infinite.
    """
    n, d = x.shape
    check = 0.0
    for i in prange(n):
        w = inv_mass[i]
        if w != 0.0:
            for c in range(d):
                vc = v[i, c] + h * (gravity[c] + (force[c] - damping * v[i, c]) * w)
                v[i, c] = vc
                xc = x[i, c] + h * vc
                x[i, c] = xc
                check += (xc + vc) * 0.0
        else:
            for c in range(d):
                check += (x[i, c] + v[i, c]) * 0.0
    return check == 0.0


@parallel_kernel
def affine_rk4(x, v, inv_mass, gravity, force, damping, h):
    """Classical RK4 for affine forces, particle by particle in registers (one pass over memory).

    Each particle's ODE x' = v, v' = g + (F - k v) / m is independent of the others, so the four
    stages need no scratch arrays. Pinned particles (1/m = 0) do not move. Returns True when
    every value of the new state is finite (the divergence check, as in ``affine_kick_drift``).
    """
    n, d = x.shape
    check = 0.0
    for i in prange(n):
        w = inv_mass[i]
        if w == 0.0:
            for c in range(d):
                check += (x[i, c] + v[i, c]) * 0.0
            continue
        for c in range(d):
            base = gravity[c] + force[c] * w
            kw = damping * w
            v0 = v[i, c]
            a1 = base - kw * v0
            v1 = v0 + 0.5 * h * a1
            a2 = base - kw * v1
            v2 = v0 + 0.5 * h * a2
            a3 = base - kw * v2
            v3 = v0 + h * a3
            a4 = base - kw * v3
            xc = x[i, c] + h / 6.0 * (v0 + 2.0 * v1 + 2.0 * v2 + v3)
            vc = v0 + h / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4)
            x[i, c] = xc
            v[i, c] = vc
            check += (xc + vc) * 0.0
    return check == 0.0


@parallel_kernel
def gather_acceleration(f, inv_mass, out):
    """a_i = f_i / m_i; exactly 0 for pinned particles (even when f_i overflowed)."""
    n, d = f.shape
    for i in prange(n):
        w = inv_mass[i]
        for c in range(d):
            out[i, c] = 0.0 if w == 0.0 else f[i, c] * w


# --- individual forces --------------------------------------------------------------------------

@parallel_kernel
def add_gravity(mass, inv_mass, g, f):
    """f_i += m_i g (free particles only: a pinned particle's infinite mass is not multiplied)."""
    n, d = f.shape
    for i in prange(n):
        if inv_mass[i] != 0.0:
            for c in range(d):
                f[i, c] += mass[i] * g[c]


@parallel_kernel
def add_linear_drag(v, k, f):
    """f_i += -k v_i."""
    n, d = f.shape
    for i in prange(n):
        for c in range(d):
            f[i, c] -= k * v[i, c]


@parallel_kernel
def add_quadratic_drag(v, coefficient, f):
    """f_i += -c |v_i| v_i."""
    n, d = f.shape
    for i in prange(n):
        s = 0.0
        for c in range(d):
            s += v[i, c] * v[i, c]
        speed = np.sqrt(s)
        for c in range(d):
            f[i, c] -= coefficient * speed * v[i, c]


@parallel_kernel
def add_wind(v, wind, k, f):
    """f_i += k (w - v_i) for one wind velocity w."""
    n, d = f.shape
    for i in prange(n):
        for c in range(d):
            f[i, c] += k * (wind[c] - v[i, c])


@parallel_kernel
def add_wind_field(v, wind, k, f):
    """f_i += k (w_i - v_i) for a sampled wind field w (N, D)."""
    n, d = f.shape
    for i in prange(n):
        for c in range(d):
            f[i, c] += k * (wind[i, c] - v[i, c])


@parallel_kernel
def add_attractor(x, mass, inv_mass, center, strength, softening, f):
    """Softened point attractor (Plummer): f_i = s m_i (c - x_i) / (|c - x_i|^2 + eps^2)^(3/2)."""
    n, d = f.shape
    eps2 = softening * softening
    for i in prange(n):
        if inv_mass[i] == 0.0:
            continue
        r2 = eps2
        for c in range(d):
            r2 += (center[c] - x[i, c]) ** 2
        scale = strength * mass[i] / (r2 * np.sqrt(r2))
        for c in range(d):
            f[i, c] += scale * (center[c] - x[i, c])


@njit(cache=True)
def attractor_energy(x, mass, inv_mass, center, strength, softening):
    """U = -s sum_i m_i / sqrt(|c - x_i|^2 + eps^2)."""
    e = 0.0
    for i in range(x.shape[0]):
        if inv_mass[i] == 0.0:
            continue
        r2 = softening * softening
        for c in range(x.shape[1]):
            r2 += (center[c] - x[i, c]) ** 2
        e -= strength * mass[i] / np.sqrt(r2)
    return e


@parallel_kernel
def add_springs_gathered(x, v, incident_start, incident_other, incident_spring,
                         stiffness, damping, rest_length, f):
    """Damped springs, gathered per particle.

    For particle i and a spring to j: d = x_i - x_j, l = |d|, n = d / l,
    f_i = -[k (l - L) + c (v_i - v_j) . n] n   (the damping acts along the spring only).
    """
    n_particles, dim = x.shape
    for i in prange(n_particles):
        for e in range(incident_start[i], incident_start[i + 1]):
            j = incident_other[e]
            s = incident_spring[e]
            l2 = 0.0
            for c in range(dim):
                l2 += (x[i, c] - x[j, c]) ** 2
            length = np.sqrt(l2)
            if length == 0.0:
                continue
            closing = 0.0
            for c in range(dim):
                closing += (v[i, c] - v[j, c]) * (x[i, c] - x[j, c])
            magnitude = stiffness[s] * (length - rest_length[s]) + damping[s] * closing / length
            for c in range(dim):
                f[i, c] -= magnitude * (x[i, c] - x[j, c]) / length


@njit(cache=True)
def springs_energy(x, pairs, stiffness, rest_length):
    """U = sum_s k_s (l_s - L_s)^2 / 2."""
    e = 0.0
    for s in range(pairs.shape[0]):
        a, b = pairs[s, 0], pairs[s, 1]
        l2 = 0.0
        for c in range(x.shape[1]):
            l2 += (x[a, c] - x[b, c]) ** 2
        stretch = np.sqrt(l2) - rest_length[s]
        e += 0.5 * stiffness[s] * stretch * stretch
    return e


@njit(cache=True)
def _spring_blocks(xi, xj, vi, vj, k, c, rest, bx, bv):
    """df_i/dx_i (bx) and df_i/dv_i (bv) of one damped spring, seen from end i.

    df_i/dx_i = -k [ max(0, 1 - L/l) (I - n n^T) + n n^T ]  (transverse term dropped when the
    spring is compressed, Choi & Ko 2002), df_i/dv_i = -c n n^T. The damping force's position
    derivative is neglected (Baraff & Witkin 1998).
    Returns False for a zero-length spring.
    """
    d = xi.shape[0]
    l2 = 0.0
    for r in range(d):
        l2 += (xi[r] - xj[r]) ** 2
    length = np.sqrt(l2)
    if length == 0.0:
        return False
    ratio = max(0.0, 1.0 - rest / length)
    for r in range(d):
        nr = (xi[r] - xj[r]) / length
        for q in range(d):
            nq = (xi[q] - xj[q]) / length
            outer = nr * nq
            ident = 1.0 if r == q else 0.0
            bx[r, q] = -k * (ratio * (ident - outer) + outer)
            bv[r, q] = -c * outer
    return True


@parallel_kernel
def spring_jacobian_blocks(x, v, pairs, stiffness, damping, rest_length, block_x, block_v):
    """Per spring s = (i, j): block_x[s] = df_i/dx_i, block_v[s] = df_i/dv_i (see _spring_blocks).

    The other blocks follow: df_i/dx_j = -B, df_j/dx_j = B, df_j/dx_i = -B. Zero-length springs get 0.
    """
    for s in prange(pairs.shape[0]):
        i, j = pairs[s, 0], pairs[s, 1]
        if not _spring_blocks(x[i], x[j], v[i], v[j], stiffness[s], damping[s], rest_length[s],
                              block_x[s], block_v[s]):
            block_x[s, :, :] = 0.0
            block_v[s, :, :] = 0.0


@parallel_kernel
def gather_spring_jacobian(incident_start, incident_spring, incident_slot, diag_slot, block_x,
                           block_v, dfdx, dfdv):
    """Per row i: (i, i) += B_s and (i, j) -= B_s over the springs at i. Row-disjoint writes."""
    dim = dfdx.shape[1]
    for i in prange(diag_slot.shape[0]):
        di = diag_slot[i]
        for e in range(incident_start[i], incident_start[i + 1]):
            s = incident_spring[e]
            o = incident_slot[e]
            for r in range(dim):
                for q in range(dim):
                    dfdx[di, r, q] += block_x[s, r, q]
                    dfdv[di, r, q] += block_v[s, r, q]
                    dfdx[o, r, q] -= block_x[s, r, q]
                    dfdv[o, r, q] -= block_v[s, r, q]


@njit(cache=True)
def add_anchor_springs(x, v, indices, anchors, stiffness, damping, rest_length, f):
    """Springs from particles to fixed points (serial: an index may repeat)."""
    dim = x.shape[1]
    for a in range(indices.shape[0]):
        i = indices[a]
        l2 = 0.0
        for c in range(dim):
            l2 += (x[i, c] - anchors[a, c]) ** 2
        length = np.sqrt(l2)
        if length == 0.0:
            continue
        closing = 0.0
        for c in range(dim):
            closing += v[i, c] * (x[i, c] - anchors[a, c])
        magnitude = stiffness[a] * (length - rest_length[a]) + damping[a] * closing / length
        for c in range(dim):
            f[i, c] -= magnitude * (x[i, c] - anchors[a, c]) / length


@njit(cache=True)
def add_anchor_jacobian(x, v, indices, anchors, diag_slot, stiffness, damping, rest_length,
                        dfdx, dfdv):
    dim = x.shape[1]
    bx = np.empty((dim, dim))
    bv = np.empty((dim, dim))
    zero = np.zeros(dim)
    for a in range(indices.shape[0]):
        i = indices[a]
        if not _spring_blocks(x[i], anchors[a], v[i], zero, stiffness[a], damping[a],
                              rest_length[a], bx, bv):
            continue
        di = diag_slot[i]
        for r in range(dim):
            for q in range(dim):
                dfdx[di, r, q] += bx[r, q]
                dfdv[di, r, q] += bv[r, q]


@njit(cache=True)
def anchor_energy(x, indices, anchors, stiffness, rest_length):
    e = 0.0
    for a in range(indices.shape[0]):
        i = indices[a]
        l2 = 0.0
        for c in range(x.shape[1]):
            l2 += (x[i, c] - anchors[a, c]) ** 2
        stretch = np.sqrt(l2) - rest_length[a]
        e += 0.5 * stiffness[a] * stretch * stretch
    return e


@parallel_kernel
def add_diagonal_jacobian(diag_slot, value, dfdv):
    """dfdv[(i,i)] += value * I (linear drag: value = -k)."""
    dim = dfdv.shape[1]
    for i in prange(diag_slot.shape[0]):
        for r in range(dim):
            dfdv[diag_slot[i], r, r] += value


@parallel_kernel
def add_quadratic_drag_jacobian(v, diag_slot, coefficient, dfdv):
    """d(-c |v| v)/dv = -c (|v| I + v v^T / |v|)."""
    n, dim = v.shape
    for i in prange(n):
        s = 0.0
        for c in range(dim):
            s += v[i, c] * v[i, c]
        speed = np.sqrt(s)
        if speed == 0.0:
            continue
        di = diag_slot[i]
        for r in range(dim):
            for q in range(dim):
                dfdv[di, r, q] -= coefficient * (v[i, r] * v[i, q] / speed + (speed if r == q else 0.0))


@njit(cache=True)
def _cell(u, count):
    """Cell index and fraction of grid coordinate u, clamped to [0, count - 1]."""
    hi = count - 1
    u = min(max(u, 0.0), float(hi))
    k = min(int(np.floor(u)), max(hi - 1, 0))
    return k, (u - k) if hi > 0 else 0.0


@parallel_kernel
def grid_sample_add_2d(x, values, origin, spacing, scale, mass, inv_mass, per_mass, f):
    """Bilinear interpolation of a (n0, n1, 2) grid at x (clamped at the border); f += scale * value."""
    n0, n1 = values.shape[0], values.shape[1]
    for i in prange(x.shape[0]):
        if inv_mass[i] == 0.0:
            continue
        a, fa = _cell((x[i, 0] - origin[0]) / spacing[0], n0)
        b, fb = _cell((x[i, 1] - origin[1]) / spacing[1], n1)
        a1, b1 = min(a + 1, n0 - 1), min(b + 1, n1 - 1)
        w = scale * (mass[i] if per_mass else 1.0)
        for c in range(2):
            lo = (1 - fa) * values[a, b, c] + fa * values[a1, b, c]
            hi = (1 - fa) * values[a, b1, c] + fa * values[a1, b1, c]
            f[i, c] += w * ((1 - fb) * lo + fb * hi)


@parallel_kernel
def grid_sample_add_3d(x, values, origin, spacing, scale, mass, inv_mass, per_mass, f):
    """Trilinear interpolation of a (n0, n1, n2, 3) grid at x (clamped at the border); f += scale * value."""
    n0, n1, n2 = values.shape[0], values.shape[1], values.shape[2]
    for i in prange(x.shape[0]):
        if inv_mass[i] == 0.0:
            continue
        a, fa = _cell((x[i, 0] - origin[0]) / spacing[0], n0)
        b, fb = _cell((x[i, 1] - origin[1]) / spacing[1], n1)
        e, fe = _cell((x[i, 2] - origin[2]) / spacing[2], n2)
        a1, b1, e1 = min(a + 1, n0 - 1), min(b + 1, n1 - 1), min(e + 1, n2 - 1)
        w = scale * (mass[i] if per_mass else 1.0)
        for c in range(3):
            c00 = (1 - fa) * values[a, b, e, c] + fa * values[a1, b, e, c]
            c10 = (1 - fa) * values[a, b1, e, c] + fa * values[a1, b1, e, c]
            c01 = (1 - fa) * values[a, b, e1, c] + fa * values[a1, b, e1, c]
            c11 = (1 - fa) * values[a, b1, e1, c] + fa * values[a1, b1, e1, c]
            f[i, c] += w * ((1 - fe) * ((1 - fb) * c00 + fb * c10) + fe * ((1 - fb) * c01 + fb * c11))
