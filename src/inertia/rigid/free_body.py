"""Free rigid bodies as a phase-space system: Witkin and Baraff's state (x, q, P, L) for B bodies.

Each body's state is its pose (position x of the centre of mass, unit quaternion q, w first) and its
linear and angular momentum (P, L) in the world frame.  The derivative is

    dx/dt = P / m
    dq/dt = 1/2 (0, omega) q,     omega = I_world^-1 L,  I_world^-1 = R diag(1/I_body) R^T
    dP/dt = F = m g + F_applied
    dL/dt = tau_applied

Using the angular momentum as the state variable makes the gyroscopic term implicit: Euler's equations
I dw/dt + w x (I w) = tau are the body-frame form of dL/dt = tau.  With no torque L is constant exactly
(bit for bit), and the integrators' error shows in the orientation, hence in the kinetic energy
1/2 L . omega.  A stage renormalises each q after every step (the integrators do not know that q must stay
on the unit sphere); it bumps ``state_revision`` so RK45 re-evaluates its first stage.

Any first-order integrator steps it: ``euler``, ``midpoint``, ``rk4``, ``rk45`` (the symplectic and implicit
ones need a second-order [x, v] system and refuse it).  Bodies are independent, so the derivative is one
kernel over all B bodies (``parallel_kernel``: serial twin below ~150 bodies).

References
- Witkin, A. and Baraff, D. (2001). Physically Based Modeling: Principles and Practice, SIGGRAPH course
  notes, "Rigid Body Dynamics" (the state x, q, P, L and its derivative).
- Landau, L. D. and Lifshitz, E. M. (1976). Mechanics, 3rd ed., section 37 (the torque-free asymmetric top,
  used by the tests).

Limitations
- Forces and torques are constant per body (``body_force``, ``body_torque``, world frame, through the
  centre of mass) plus uniform gravity; no contacts, joints or damping (those belong to the world step).
- The body frame must be the principal frame at the centre of mass (``geometry.mass.principal_frame``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import prange

from inertia._jit import parallel_kernel
from inertia.math import rotate_vectors
from inertia.ode.system import PhaseSpaceSystem

__all__ = ["FreeBodies", "QuaternionRenormalization"]

POSE_SIZE = 7      # px, py, pz, qw, qx, qy, qz
MOMENTUM_SIZE = 6  # Lx, Ly, Lz, Px, Py, Pz  (angular first, Featherstone's order)


@parallel_kernel
def free_body_derivative(y, inv_mass, inv_inertia, force, torque, gravity, out):
    """dy/dt of B free bodies; y and out are flat (13 B,) = [pose (B, 7) | momentum (B, 6)].

    inv_mass (B,) 1/kg; inv_inertia (B, 3) 1/(kg m^2) principal; force, torque (B, 3) N, N m (world);
    gravity (3,) m/s^2."""
    body_count = inv_mass.shape[0]
    mom = POSE_SIZE * body_count
    for b in prange(body_count):
        p = POSE_SIZE * b
        m = mom + MOMENTUM_SIZE * b
        qw, qx, qy, qz = y[p + 3], y[p + 4], y[p + 5], y[p + 6]
        lx, ly, lz = y[m], y[m + 1], y[m + 2]
        # omega = R diag(1/I) R^T L with R from the normalised q (q may drift off the unit sphere within a step)
        s = 1.0 / (qw * qw + qx * qx + qy * qy + qz * qz)
        r00 = 1.0 - 2.0 * s * (qy * qy + qz * qz)
        r01 = 2.0 * s * (qx * qy - qw * qz)
        r02 = 2.0 * s * (qx * qz + qw * qy)
        r10 = 2.0 * s * (qx * qy + qw * qz)
        r11 = 1.0 - 2.0 * s * (qx * qx + qz * qz)
        r12 = 2.0 * s * (qy * qz - qw * qx)
        r20 = 2.0 * s * (qx * qz - qw * qy)
        r21 = 2.0 * s * (qy * qz + qw * qx)
        r22 = 1.0 - 2.0 * s * (qx * qx + qy * qy)
        # body-frame angular velocity: diag(1/I) R^T L
        bx = inv_inertia[b, 0] * (r00 * lx + r10 * ly + r20 * lz)
        by = inv_inertia[b, 1] * (r01 * lx + r11 * ly + r21 * lz)
        bz = inv_inertia[b, 2] * (r02 * lx + r12 * ly + r22 * lz)
        wx = r00 * bx + r01 * by + r02 * bz
        wy = r10 * bx + r11 * by + r12 * bz
        wz = r20 * bx + r21 * by + r22 * bz
        # dx/dt = P / m
        im = inv_mass[b]
        out[p] = y[m + 3] * im
        out[p + 1] = y[m + 4] * im
        out[p + 2] = y[m + 5] * im
        # dq/dt = 1/2 (0, w) q
        out[p + 3] = 0.5 * (-wx * qx - wy * qy - wz * qz)
        out[p + 4] = 0.5 * (wx * qw + wy * qz - wz * qy)
        out[p + 5] = 0.5 * (-wx * qz + wy * qw + wz * qx)
        out[p + 6] = 0.5 * (wx * qy - wy * qx + wz * qw)
        # dL/dt = tau, dP/dt = m g + F  (a body with inv_mass 0 feels no gravity)
        out[m] = torque[b, 0]
        out[m + 1] = torque[b, 1]
        out[m + 2] = torque[b, 2]
        mass = 1.0 / im if im > 0.0 else 0.0
        out[m + 3] = mass * gravity[0] + force[b, 0]
        out[m + 4] = mass * gravity[1] + force[b, 1]
        out[m + 5] = mass * gravity[2] + force[b, 2]


@parallel_kernel
def normalize_quaternions(pose):
    """q <- q / |q| for each row of pose (B, 7)."""
    for b in prange(pose.shape[0]):
        n = math.sqrt(pose[b, 3] ** 2 + pose[b, 4] ** 2 + pose[b, 5] ** 2 + pose[b, 6] ** 2)
        inv = 1.0 / n
        for k in range(3, 7):
            pose[b, k] *= inv


@parallel_kernel
def angular_velocities(pose, momentum, inv_inertia, out):
    """World angular velocity omega = R diag(1/I) R^T L of each body: out (B, 3)."""
    for b in prange(pose.shape[0]):
        qw, qx, qy, qz = pose[b, 3], pose[b, 4], pose[b, 5], pose[b, 6]
        s = 1.0 / (qw * qw + qx * qx + qy * qy + qz * qz)
        r00 = 1.0 - 2.0 * s * (qy * qy + qz * qz)
        r01 = 2.0 * s * (qx * qy - qw * qz)
        r02 = 2.0 * s * (qx * qz + qw * qy)
        r10 = 2.0 * s * (qx * qy + qw * qz)
        r11 = 1.0 - 2.0 * s * (qx * qx + qz * qz)
        r12 = 2.0 * s * (qy * qz - qw * qx)
        r20 = 2.0 * s * (qx * qz - qw * qy)
        r21 = 2.0 * s * (qy * qz + qw * qx)
        r22 = 1.0 - 2.0 * s * (qx * qx + qy * qy)
        lx, ly, lz = momentum[b, 0], momentum[b, 1], momentum[b, 2]
        bx = inv_inertia[b, 0] * (r00 * lx + r10 * ly + r20 * lz)
        by = inv_inertia[b, 1] * (r01 * lx + r11 * ly + r21 * lz)
        bz = inv_inertia[b, 2] * (r02 * lx + r12 * ly + r22 * lz)
        out[b, 0] = r00 * bx + r01 * by + r02 * bz
        out[b, 1] = r10 * bx + r11 * by + r12 * bz
        out[b, 2] = r20 * bx + r21 * by + r22 * bz


class QuaternionRenormalization:
    """Step stage: puts every body's quaternion back on the unit sphere after the integrator step."""

    stage_order = 10

    def begin_step(self, system, t, dt):
        pass

    def end_step(self, system, t, dt):
        normalize_quaternions(system.body_pose)
        system.state_modified()

    def get_state(self) -> dict:
        return {}

    def set_state(self, state: dict) -> None:
        pass


def _rows(value, name, count, default):
    if value is None:
        return np.tile(np.asarray(default, dtype=np.float64), (count, 1))
    arr = np.asarray(value, dtype=np.float64)
    width = len(default)
    if arr.shape == (width,):
        arr = np.tile(arr, (count, 1))
    if arr.shape != (count, width) or not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be a finite array of shape ({count}, {width}) or ({width},); "
                         f"got shape {np.shape(value)}")
    return arr


class FreeBodies(PhaseSpaceSystem):
    """B free rigid bodies (first-order phase-space system; step with euler, midpoint, rk4 or rk45).

    Parameters
    ----------
    masses : (B,) kg, > 0.
    inertia_diag : (B, 3) or (3,) kg m^2, principal moments (> 0) about the centre of mass.
    positions : (B, 3) m, centre of mass (0 default).
    orientations : (B, 4) unit quaternions (w, x, y, z) body -> world (identity default; normalised here).
    velocities : (B, 3) m/s of the centre of mass (0 default).
    angular_velocities : (B, 3) rad/s, world frame (0 default).
    gravity : (3,) m/s^2, uniform (0 default).

    State (views into ``state``, written by the integrator):
    body_pose (B, 7) [px, py, pz, qw, qx, qy, qz]; body_momentum (B, 6) [L (kg m^2/s), P (kg m/s)], world.
    Inputs the user may change between steps: ``body_force`` (B, 3) N and ``body_torque`` (B, 3) N m, world
    frame, through the centre of mass (constant over a step).
    """

    second_order = False

    def __init__(self, masses, inertia_diag, *, positions=None, orientations=None, velocities=None,
                 angular_velocities=None, gravity=(0.0, 0.0, 0.0)):
        mass = np.atleast_1d(np.asarray(masses, dtype=np.float64)).copy()
        if mass.ndim != 1 or mass.size == 0 or not np.all(np.isfinite(mass)) or np.any(mass <= 0):
            raise ValueError(f"masses must be a non-empty (B,) array of finite numbers > 0; got {np.asarray(masses)!r}")
        count = mass.shape[0]
        inertia = _rows(inertia_diag, "inertia_diag", count, (1.0, 1.0, 1.0))
        if np.any(inertia <= 0):
            raise ValueError(f"inertia_diag must be > 0 (principal moments); rows "
                             f"{np.flatnonzero(np.any(inertia <= 0, axis=1))[:10].tolist()} are not")
        i_sorted = np.sort(inertia, axis=1)
        if np.any(i_sorted[:, 0] + i_sorted[:, 1] < i_sorted[:, 2] * (1 - 1e-12)):
            raise ValueError("inertia_diag must satisfy the triangle inequality I1 + I2 >= I3 of a real body")
        x = _rows(positions, "positions", count, (0.0, 0.0, 0.0))
        q = _rows(orientations, "orientations", count, (1.0, 0.0, 0.0, 0.0))
        qn = np.linalg.norm(q, axis=1)
        if np.any(qn == 0):
            raise ValueError("orientations must be non-zero quaternions (w, x, y, z)")
        q = q / qn[:, None]
        v = _rows(velocities, "velocities", count, (0.0, 0.0, 0.0))
        w = _rows(angular_velocities, "angular_velocities", count, (0.0, 0.0, 0.0))
        g = np.asarray(gravity, dtype=np.float64).reshape(-1)
        if g.shape != (3,) or not np.all(np.isfinite(g)):
            raise ValueError(f"gravity must be 3 finite numbers (m/s^2); got {gravity!r}")

        self.body_count = count
        self.body_mass = mass
        self.body_inv_mass = 1.0 / mass
        self.body_inertia = inertia
        self.body_inv_inertia = 1.0 / inertia
        self.gravity = g
        self.body_force = np.zeros((count, 3))
        self.body_torque = np.zeros((count, 3))
        self.state = np.zeros((POSE_SIZE + MOMENTUM_SIZE) * count)
        self.position_size = 0
        self.body_pose = self.state[:POSE_SIZE * count].reshape(count, POSE_SIZE)
        self.body_momentum = self.state[POSE_SIZE * count:].reshape(count, MOMENTUM_SIZE)
        self.body_pose[:, :3] = x
        self.body_pose[:, 3:] = q
        # L = R diag(I) R^T w, P = m v (quaternion rotations in plain arithmetic: a BLAS matrix product
        # rounds differently with the CPU's kernel, and the state would hash differently per machine)
        q_inv = q * np.array([1.0, -1.0, -1.0, -1.0])
        self.body_momentum[:, :3] = rotate_vectors(q, inertia * rotate_vectors(q_inv, w))
        self.body_momentum[:, 3:] = mass[:, None] * v
        self.stages = [QuaternionRenormalization()]
        self.state_revision = 0
        self._omega = np.zeros((count, 3))

    # ---- phase-space interface
    def derivative(self, y, t, out) -> None:
        free_body_derivative(y, self.body_inv_mass, self.body_inv_inertia, self.body_force, self.body_torque,
                             self.gravity, out)

    def add_stage(self, stage) -> None:
        self.stages.append(stage)
        self.stages.sort(key=lambda s: getattr(s, "stage_order", 50))

    def get_state(self) -> dict:
        return {"state": self.state.copy(), "state_revision": self.state_revision,
                "body_force": self.body_force.copy(), "body_torque": self.body_torque.copy(),
                "stages": [s.get_state() for s in self.stages]}

    def set_state(self, saved: dict) -> None:
        self.state[:] = saved["state"]
        self.body_force[:] = saved["body_force"]
        self.body_torque[:] = saved["body_torque"]
        for stage, s in zip(self.stages, saved["stages"]):
            stage.set_state(s)
        self.state_revision = saved["state_revision"]

    def describe_particles(self, indices) -> str:
        """Names the bodies owning the non-finite state entries (used by Simulation's divergence report)."""
        indices = np.asarray(indices)
        return f"free bodies {indices[:8].tolist()}{' ...' if indices.size > 8 else ''}"

    def stability_hint(self, dt: float) -> str:
        w = np.linalg.norm(self.body_angular_velocity, axis=1)
        if w.size and np.all(np.isfinite(w)) and w.max() * dt > 0.5:
            return f"a body spins at {w.max():.3g} rad/s, {w.max() * dt:.2g} rad per step"
        return ""

    # ---- derived quantities (computed on request)
    @property
    def body_position(self) -> np.ndarray:
        """(B, 3) view of the centre-of-mass positions, m."""
        return self.body_pose[:, :3]

    @property
    def body_orientation(self) -> np.ndarray:
        """(B, 4) view of the orientations (w, x, y, z)."""
        return self.body_pose[:, 3:]

    @property
    def body_velocity(self) -> np.ndarray:
        """(B, 3) centre-of-mass velocity P / m, m/s (a new array)."""
        return self.body_momentum[:, 3:] * self.body_inv_mass[:, None]

    @property
    def body_angular_velocity(self) -> np.ndarray:
        """(B, 3) world angular velocity, rad/s (a new array)."""
        out = np.zeros((self.body_count, 3))
        angular_velocities(self.body_pose, self.body_momentum, self.body_inv_inertia, out)
        return out

    def kinetic_energy(self) -> np.ndarray:
        """(B,) kinetic energy P^2 / (2 m) + L . omega / 2, J."""
        p = self.body_momentum[:, 3:]
        lin = 0.5 * np.einsum("ij,ij->i", p, p) * self.body_inv_mass
        return lin + 0.5 * np.einsum("ij,ij->i", self.body_momentum[:, :3], self.body_angular_velocity)

    def body_frame_angular_momentum(self) -> np.ndarray:
        """(B, 3) angular momentum in each body's principal frame, R^T L."""
        q = self.body_pose[:, 3:]
        q_inv = q * np.array([1.0, -1.0, -1.0, -1.0]) / np.linalg.norm(q, axis=1)[:, None]
        return rotate_vectors(q_inv, self.body_momentum[:, :3])
