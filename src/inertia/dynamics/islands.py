"""Islands and sleeping: union-find over touching contacts in a fixed order, per-island sleep timers.

Stages (read -> write)
- ``wake_touched`` (islands stage, before the solve): a contact between an awake body (or a moving
  kinematic body) and a sleeping dynamic body wakes the sleeping body's whole island (all bodies that
  went to sleep with it, ``body_sleep_island``).
- ``update_sleep`` (finalize stage, after the solve): a dynamic body below both velocity tolerances
  accumulates ``body_sleep_time``; contacts between dynamic bodies join islands (union-find with
  union by smaller index, so the result does not depend on thread count); an island whose smallest
  timer reaches ``time_to_sleep`` goes to sleep as one: velocities zeroed, ``body_awake`` False.
  A body touching a moving kinematic body never sleeps.

Sleeping bodies keep their contacts with awake bodies; pairs of two sleeping bodies are skipped by the
broad phase, which is where a resting pile saves its time.

References: Catto, E. (2024). Box2D v3 islands and sleep (persistent islands, time to sleep);
Tarjan, R. E. (1975). Efficiency of a good but not linear set union algorithm.
Limitations: islands are rebuilt from the current contacts every step (no persistent island graph);
no joints yet (they will join islands the same way).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..geometry import shapes as S

__all__ = ["wake_touched", "update_sleep"]


@njit(cache=True)
def _find(parent, x):
    root = x
    while parent[root] != root:
        root = parent[root]
    while parent[x] != root:          # path compression
        nxt = parent[x]
        parent[x] = root
        x = nxt
    return root


@njit(cache=True)
def _moving_kinematic(b, body_type, body_qd):
    if b < 0 or body_type[b] != S.KINEMATIC:
        return False
    s = 0.0
    for k in range(6):
        s += body_qd[b, k] * body_qd[b, k]
    return s > 0.0


@njit(cache=True)
def wake_touched(active, n_active, contact_body, contact_is_sensor, body_type, body_awake, body_qd,
                 body_sleep_time, body_sleep_island):
    """Wake every sleeping island touched by an awake dynamic or moving kinematic body. Returns the
    number of bodies woken."""
    woken = 0
    for t in range(n_active):
        i = active[t]
        if contact_is_sensor[i]:
            continue
        for side in range(2):
            x = contact_body[i, side]
            o = contact_body[i, 1 - side]
            if x < 0 or body_type[x] != S.DYNAMIC or body_awake[x]:
                continue
            other_awake = o >= 0 and ((body_type[o] == S.DYNAMIC and body_awake[o])
                                      or _moving_kinematic(o, body_type, body_qd))
            if not other_awake:
                continue
            isl = body_sleep_island[x]
            for b in range(body_awake.shape[0]):
                if not body_awake[b] and body_sleep_island[b] == isl and body_type[b] == S.DYNAMIC:
                    body_awake[b] = True
                    body_sleep_time[b] = 0.0
                    woken += 1
    return woken


@njit(cache=True)
def update_sleep(active, n_active, contact_body, contact_is_sensor, body_type, body_awake, body_qd,
                 body_sleep_time, body_sleep_island, parent, island_min, dt, linear_tol, angular_tol,
                 time_to_sleep, body_bound_radius):
    """Advance sleep timers, build islands, put resting islands to sleep. Returns bodies put to sleep.

    A body rests when |v| <= linear_tol and |w| <= max(angular_tol, linear_tol / bound_radius): its
    farthest point moves no faster than linear_tol by rotation (Box2D v3 measures the sleep speed at
    the body's maximum extent the same way), so a large body needs a slow spin, a small one may rock
    a little faster without keeping a whole pile awake."""
    nb = body_awake.shape[0]
    for b in range(nb):
        parent[b] = b
        if body_type[b] != S.DYNAMIC or not body_awake[b]:
            continue
        qd = body_qd[b]
        w = math.sqrt(qd[0] * qd[0] + qd[1] * qd[1] + qd[2] * qd[2])
        v = math.sqrt(qd[3] * qd[3] + qd[4] * qd[4] + qd[5] * qd[5])
        r = body_bound_radius[b]
        w_tol = max(angular_tol, linear_tol / r) if r > 0.0 else angular_tol
        if v > linear_tol or w > w_tol:
            body_sleep_time[b] = 0.0
        else:
            body_sleep_time[b] += dt
    # union over contacts between two dynamic bodies; moving kinematic bodies keep partners awake
    for t in range(n_active):
        i = active[t]
        if contact_is_sensor[i]:
            continue
        a, b = contact_body[i, 0], contact_body[i, 1]
        if _moving_kinematic(a, body_type, body_qd) and b >= 0:
            body_sleep_time[b] = 0.0
        if _moving_kinematic(b, body_type, body_qd) and a >= 0:
            body_sleep_time[a] = 0.0
        if a < 0 or b < 0 or body_type[a] != S.DYNAMIC or body_type[b] != S.DYNAMIC:
            continue
        ra, rb = _find(parent, a), _find(parent, b)
        if ra != rb:
            if ra < rb:
                parent[rb] = ra
            else:
                parent[ra] = rb
    for b in range(nb):
        island_min[b] = np.inf
    for b in range(nb):
        if body_type[b] != S.DYNAMIC or not body_awake[b]:
            continue
        r = _find(parent, b)
        island_min[r] = min(island_min[r], body_sleep_time[b])
    slept = 0
    for b in range(nb):
        if body_type[b] != S.DYNAMIC or not body_awake[b]:
            continue
        r = _find(parent, b)
        if island_min[r] >= time_to_sleep:
            body_awake[b] = False
            body_sleep_island[b] = r
            for k in range(6):
                body_qd[b, k] = 0.0
            slept += 1
    return slept
