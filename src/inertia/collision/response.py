"""Contact response: velocity updates with restitution and Coulomb friction (Numba).

Point against a moving surface (Witkin & Baraff's point-plane response, generalised)
------------------------------------------------------------------------------------
With the surface velocity u and unit normal N, the relative velocity w = v - u splits into
``w_N = (N.w) N`` and ``w_T = w - w_N``. A particle heading in (N.w < 0) leaves with

    w_N' = -e w_N                    (restitution e; e = 0 below the resting speed)
    w_T' = max(0, 1 - mu |dw_N| / |w_T|) w_T     (Coulomb friction as an impulse bound)

where ``|dw_N| = (1 + e) |N.w|`` is the normal velocity change: friction can remove at most
``mu`` times the normal impulse, so tangential motion below that bound stops (static), above it
is reduced by exactly that amount (kinetic) (Bridson, Fedkiw & Anderson 2002, sec. 7.2).
Impacts slower than the resting speed (about twice the velocity the applied forces add in one
step) are treated as inelastic, so that a bouncing particle comes to rest instead of chattering.

Pair of spheres (impulse, momentum conserving; ``particle_kernels._pair_velocity``)
---------------------------------------------------------------------------------
For particles i, j with inverse masses w_i, w_j, normal n from i to j and relative normal
velocity ``v_n = n.(v_j - v_i) < 0``: the normal impulse ``P = -(1 + e) v_n / (w_i + w_j)``
is applied as ``v_i -= w_i P n, v_j += w_j P n``; a tangential impulse of at most ``mu P``
opposes the relative tangential velocity. Equal and opposite impulses conserve momentum
exactly; with e = 1 each pair exchange conserves kinetic energy.

References
----------
- Witkin, A. & Baraff, D. (2001), *Physically Based Modeling*, SIGGRAPH course notes,
  "Particle System Dynamics", collision and contact with a plane.
- Bridson, R., Fedkiw, R. & Anderson, J. (2002), "Robust treatment of collisions, contact and
  friction for cloth animation", SIGGRAPH: friction as a bound on the tangential impulse.
- Guendelman, E., Bridson, R. & Fedkiw, R. (2003), "Nonconvex rigid bodies with stacking",
  SIGGRAPH: restitution switched off for slow (resting) contacts; separate velocity and
  position passes.

Limitations
-----------
- Friction is isotropic Coulomb with one coefficient for static and kinetic friction.
- Particles are points or spheres without rotation: no rolling or spin.
"""

from __future__ import annotations

import math

from numba import njit


@njit(cache=True)
def surface_response(vx, vy, vz, ux, uy, uz, nx, ny, nz, restitution, friction, rest_speed):
    """New velocity of a point hitting a surface (normal n, surface velocity u).

    Returns (vx', vy', vz', changed). Unchanged when the point is not heading in.
    """
    wx, wy, wz = vx - ux, vy - uy, vz - uz
    wn = wx * nx + wy * ny + wz * nz
    if wn >= 0.0:
        return vx, vy, vz, False
    e = restitution if -wn > rest_speed else 0.0
    tx, ty, tz = wx - wn * nx, wy - wn * ny, wz - wn * nz
    # Coulomb bound on the tangential impulse: mu times the normal velocity change
    dvn = -(1.0 + e) * wn
    tl = math.sqrt(tx * tx + ty * ty + tz * tz)
    scale = 0.0
    if tl > friction * dvn:
        scale = 1.0 - friction * dvn / tl
    wn_new = -e * wn
    return (ux + scale * tx + wn_new * nx, uy + scale * ty + wn_new * ny,
            uz + scale * tz + wn_new * nz, True)
