"""Particle emitters: spawn particles at a rate into a preallocated pool, age them, retire them.

References: Reeves, W. T. (1983), "Particle Systems -- a Technique for Modeling a Class of Fuzzy
Objects", ACM TOG 2(2): emission rate, initial position/velocity distributions, lifetime.

An emitter is a step stage of its particle system (``end_step`` after the integrator): it ages
the live particles it owns, retires those past their lifetime (inactive, zero velocity, parked at
the emitter), then spawns ``rate * dt`` new ones (the fractional remainder carries over), drawing
positions, velocities and lifetimes from a seeded NumPy generator into preallocated buffers.

Limitations: a full pool drops new particles (counted in ``dropped``); several emitters on one
system share the pool first come, first served.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .. import _validate as V

__all__ = ["Emitter", "PointSource", "DiskSource", "BoxSource", "SphereSource", "Cone"]


# ---- distributions: each draws k samples into out[:k] from a numpy Generator -------------------

class PointSource:
    """All particles start at one point."""

    def __init__(self, point):
        self.point = V.as_vector(point, "PointSource point")

    def draw(self, rng, out):
        out[:] = self.point


class BoxSource:
    """Uniform in an axis-aligned box (center, half_extents)."""

    def __init__(self, center, half_extents):
        self.center = V.as_vector(center, "BoxSource center")
        self.half_extents = V.as_vector(half_extents, "BoxSource half_extents", self.center.shape[0])
        if np.any(self.half_extents < 0):
            raise ValueError("BoxSource half_extents must be >= 0")

    def draw(self, rng, out):
        rng.random(out=out)
        out *= 2.0 * self.half_extents
        out += self.center - self.half_extents


class SphereSource:
    """Uniform in a ball (3D) or disk (2D) of `radius` around `center`."""

    def __init__(self, center, radius):
        self.center = V.as_vector(center, "SphereSource center")
        self.radius = V.positive_scalar(radius, "SphereSource radius", allow_zero=True)

    def draw(self, rng, out):
        d = out.shape[1]
        out[:] = rng.standard_normal(out.shape)
        out /= np.linalg.norm(out, axis=1, keepdims=True) + 1e-300
        out *= (self.radius * rng.random(out.shape[0]) ** (1.0 / d))[:, None]
        out += self.center


class DiskSource:
    """Uniform on a disk of `radius` centred at `center` with normal `normal` (3D only)."""

    def __init__(self, center, radius, normal=(0.0, 0.0, 1.0)):
        self.center = V.as_vector(center, "DiskSource center", 3)
        self.radius = V.positive_scalar(radius, "DiskSource radius", allow_zero=True)
        n = V.as_vector(normal, "DiskSource normal", 3)
        if np.linalg.norm(n) == 0:
            raise ValueError("DiskSource normal must be non-zero")
        self.normal = n / np.linalg.norm(n)
        self._u, self._w = _orthonormal_basis(self.normal)

    def draw(self, rng, out):
        k = out.shape[0]
        r = self.radius * np.sqrt(rng.random(k))
        phi = 2 * np.pi * rng.random(k)
        out[:] = self.center + (r * np.cos(phi))[:, None] * self._u + (r * np.sin(phi))[:, None] * self._w


class Cone:
    """Velocities within `spread` radians of `direction`, speed uniform in speed * (1 +/- speed_jitter)."""

    def __init__(self, direction, speed, spread=0.0, speed_jitter=0.0):
        d = V.as_vector(direction, "Cone direction")
        if np.linalg.norm(d) == 0:
            raise ValueError("Cone direction must be non-zero")
        self.direction = d / np.linalg.norm(d)
        self.speed = V.positive_scalar(speed, "Cone speed", allow_zero=True)
        self.spread = V.positive_scalar(spread, "Cone spread", allow_zero=True)
        if self.spread > np.pi:
            raise ValueError(f"Cone spread must be in [0, pi] radians; got {spread}")
        self.speed_jitter = V.positive_scalar(speed_jitter, "Cone speed_jitter", allow_zero=True)
        if len(self.direction) == 3:
            self._u, self._w = _orthonormal_basis(self.direction)

    def draw(self, rng, out):
        k, d = out.shape
        speed = self.speed * (1.0 + self.speed_jitter * (2.0 * rng.random(k) - 1.0))
        if d == 2:
            base = np.arctan2(self.direction[1], self.direction[0])
            angle = base + self.spread * (2.0 * rng.random(k) - 1.0)
            out[:, 0], out[:, 1] = np.cos(angle), np.sin(angle)
        else:
            # uniform over the spherical cap of half-angle `spread`
            cos_t = 1.0 - rng.random(k) * (1.0 - np.cos(self.spread))
            sin_t = np.sqrt(np.maximum(0.0, 1.0 - cos_t * cos_t))
            phi = 2 * np.pi * rng.random(k)
            out[:] = (cos_t[:, None] * self.direction + (sin_t * np.cos(phi))[:, None] * self._u
                      + (sin_t * np.sin(phi))[:, None] * self._w)
        out *= speed[:, None]


def _orthonormal_basis(n):
    helper = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(n, helper)
    u /= np.linalg.norm(u)
    return u, np.cross(n, u)


def _as_source(value, name):
    if hasattr(value, "draw"):
        return value
    return PointSource(V.as_vector(value, name))


def _as_velocity(value, name):
    if hasattr(value, "draw"):
        return value
    vec = V.as_vector(value, name)
    speed = float(np.linalg.norm(vec))
    return Cone(vec if speed > 0 else np.eye(len(vec))[0], speed, 0.0)


@njit(cache=True)
def _find_free_slots(active, count, out):
    """Write the indices of the first `count` inactive particles into out; return how many were found."""
    found = 0
    for i in range(active.shape[0]):
        if found == count:
            break
        if not active[i]:
            out[found] = i
            found += 1
    return found


@njit(cache=True)
def _spawn(slots, positions, velocities, lifetimes, emitter_id, x, v, active, owner, age, lifetime,
           mass, inv_mass, node_free):
    """Activate the particles in `slots` with their drawn initial state."""
    for k in range(slots.shape[0]):
        i = slots[k]
        for c in range(x.shape[1]):
            x[i, c] = positions[k, c]
            v[i, c] = velocities[k, c]
        active[i] = True
        owner[i] = emitter_id
        age[i] = 0.0
        lifetime[i] = lifetimes[k]
        inv_mass[i] = 1.0 / mass[i]
        node_free[i] = inv_mass[i] > 0.0


@njit(cache=True)
def _age_and_retire(owner, active, age, lifetime, v, inv_mass, node_free, emitter_id, dt):
    """Age this emitter's live particles; retire those whose age reached their lifetime."""
    retired = 0
    for i in range(owner.shape[0]):
        if owner[i] != emitter_id or not active[i]:
            continue
        age[i] += dt
        if age[i] >= lifetime[i]:
            active[i] = False
            inv_mass[i] = 0.0
            node_free[i] = False
            owner[i] = -1
            for c in range(v.shape[1]):
                v[i, c] = 0.0
            retired += 1
    return retired


class Emitter:
    """Emit particles into a `ParticleSystem.pool`.

    Parameters
    ----------
    rate : particles per second (> 0).
    position : a point (D,) or a source (`PointSource`, `BoxSource`, `SphereSource`, `DiskSource`).
    velocity : a vector (D,) or a `Cone`.
    lifetime : seconds, scalar or (min, max) uniform; inf = forever.
    start, stop : emission window in seconds (stop=inf: emit forever).
    seed : seed of this emitter's random generator (runs are deterministic).
    """

    stage_order = 90  # after collision response: a new particle starts its first step unclipped

    def __init__(self, rate, position, velocity, lifetime=float("inf"), *, start=0.0,
                 stop=float("inf"), seed=0):
        self.rate = V.positive_scalar(rate, "Emitter rate")
        self.position = _as_source(position, "Emitter position")
        self.velocity = _as_velocity(velocity, "Emitter velocity")
        lo, hi = (lifetime, lifetime) if np.ndim(lifetime) == 0 else tuple(lifetime)
        if not (float(lo) > 0 and float(hi) >= float(lo)):
            raise ValueError(f"Emitter lifetime must be > 0 (a number or (min, max) with min <= max); got {lifetime!r}")
        self.lifetime = (float(lo), float(hi))
        self.start, self.stop = float(start), float(stop)
        if not self.stop > self.start:
            raise ValueError(f"Emitter stop must be after start; got start={start}, stop={stop}")
        self.seed = seed
        self.rng = np.random.default_rng(seed)
        self.carry = 0.0
        self.dropped = 0
        self.system = None

    def bind(self, system):
        if self.system is not None:
            raise ValueError("this Emitter is already added to a system")
        self.system = system
        n, d = system.particle_count, system.dim
        self.id = len(system.emitters)
        if not hasattr(system, "_emitter_owner"):
            system._emitter_owner = np.full(n, -1, dtype=np.int64)
            system.particle_age = np.zeros(n)
            system.particle_lifetime = np.full(n, np.inf)
        self._positions = np.zeros((n, d))
        self._velocities = np.zeros((n, d))
        self._lifetimes = np.zeros(n)
        self._slots = np.zeros(n, dtype=np.int64)

    def begin_step(self, system, t, dt):
        pass

    def end_step(self, system, t, dt):
        s = system
        retired = _age_and_retire(s._emitter_owner, s.active, s.particle_age, s.particle_lifetime,
                                  s.v, s.inv_mass, s.node_free, self.id, dt)
        # emit rate * (the part of this step inside [start, stop]); the fraction carries over
        window = max(0.0, min(t + dt, self.stop) - max(t, self.start))
        self.carry += self.rate * window
        wanted = int(self.carry)
        self.carry -= wanted
        count = _find_free_slots(s.active, wanted, self._slots) if wanted else 0
        self.dropped += wanted - count
        if count:
            self.position.draw(self.rng, self._positions[:count])
            self.velocity.draw(self.rng, self._velocities[:count])
            lo, hi = self.lifetime
            if lo == hi:
                self._lifetimes[:count] = lo
            else:
                self._lifetimes[:count] = self.rng.uniform(lo, hi, count)
            _spawn(self._slots[:count], self._positions[:count], self._velocities[:count],
                   self._lifetimes[:count], self.id, s.x, s.v, s.active, s._emitter_owner,
                   s.particle_age, s.particle_lifetime, s.mass, s.inv_mass, s.node_free)
        if count or retired:
            # retiring zeroes velocities; spawned values are finite unless a user distribution
            # made them otherwise (then the simulation checks the whole state)
            spawned_finite = count == 0 or bool(np.isfinite(self._positions[:count]).all()
                                                and np.isfinite(self._velocities[:count]).all())
            s.state_modified(finite=spawned_finite)

    def get_state(self):
        s = self.system
        return {"rng": self.rng.bit_generator.state, "carry": self.carry, "dropped": self.dropped,
                "owner": s._emitter_owner.copy(), "age": s.particle_age.copy(),
                "lifetime": s.particle_lifetime.copy()}

    def set_state(self, state):
        s = self.system
        self.rng.bit_generator.state = state["rng"]
        self.carry, self.dropped = state["carry"], state["dropped"]
        s._emitter_owner[:] = state["owner"]
        s.particle_age[:] = state["age"]
        s.particle_lifetime[:] = state["lifetime"]
