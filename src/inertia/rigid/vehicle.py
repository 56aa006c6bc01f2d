"""Raycast vehicle: a rigid chassis on wheels that are ray casts (suspension, tyre friction, steering,
engine and brake torque), after the classic game-engine design (Bullet's btRaycastVehicle; Millington
2007, Game Physics Engine Development, ch. on vehicles) with a slip-cancelling tyre.

Per world step, `RaycastVehicle.update` (call it before ``world.step()``), for every wheel:
1. Ray from the wheel's hardpoint along the chassis's down axis, length ``rest_length + radius``
   (`inertia.rigid.queries.WorldQueries`, the chassis's own shapes skipped). A hit at distance d compresses
   the spring by c = rest_length + radius - d.
2. Suspension (spring-damper; applied along the ground normal at the contact, as Bullet does, so a
   pitching chassis gets no horizontal push from its tilted springs): F_s = max(0, k c + damping dc/dt), dc/dt the
   hardpoint's velocity along the ray. At rest a chassis of mass m on four equal wheels sags m g / (4 k).
3. Tyre (at the contact point, in the ground plane: forward f = steered wheel heading, lateral l = n x f).
   The slip velocities are s_long = v_c . f - omega r and s_lat = v_c . l. The force that would cancel each
   within the step, F = -s / (dt (1/m_q + r^2/I_w)) longitudinally (m_q = m / wheel count, I_w the wheel's
   spin inertia; the r^2/I_w term drops laterally), is clipped to the friction circle |F| <= mu F_s
   (Coulomb). Steered wheels follow Ackermann geometry (each square to the turn centre). So a rolling car follows the kinematic bicycle model at low speed (radius L / tan(delta)), and
   locked wheels slide at mu F_s (stopping distance v0^2 / (2 mu g)).
4. Wheel spin: engine torque, then the brake torque brings omega towards zero without passing it; if it
   stops the wheel and can hold it against the tyre force, the wheel is locked (its slip is taken up by
   the chassis alone, F = -s_long m_q / dt before clipping), else I_w d(omega)/dt = -F_long r is added.
The sum of the wheel forces and their torques about the centre of mass is written to
``world.control.body_force/body_torque[chassis]`` (it replaces what was there), constant over the step.

References
- Millington, I. (2007). Game Physics Engine Development. Morgan Kaufmann (raycast wheels).
- Coumans, E. Bullet Physics, btRaycastVehicle (the design: rays as wheels, friction clamped by the
  suspension load).
- Rajamani, R. (2012). Vehicle Dynamics and Control, 2nd ed., 2.2 (kinematic bicycle model).

Limitations
- No tyre model with slip curves (Pacejka): the tyre is rigid until it slides (infinite cornering
  stiffness), so there is no understeer gradient; no rolling resistance or aerodynamic drag.
- Forces are explicit and constant over one world step (stiff springs need small dt: keep
  sqrt(4 k / m) dt < 0.5); the wheel is a ray, not a swept cylinder, so it can drop into a crack narrower
  than the wheel and a kerb is met only below the hardpoint.
- The per-step work is a Python loop over the wheels (a few ray casts each); fine for a few vehicles, not
  for hundreds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .._validate import positive_scalar
from ..math import quat_to_mat3

from .queries import WorldQueries

__all__ = ["Wheel", "RaycastVehicle"]


@dataclass
class Wheel:
    """One wheel. ``hardpoint`` (3,) m in the chassis's body frame (centre of mass, principal axes) where
    the suspension is attached; the wheel hangs along the chassis's -z. ``rest_length`` m spring length
    with no load, ``radius`` m, ``stiffness`` N/m, ``damping`` N s/m, ``friction`` (Coulomb mu),
    ``inertia`` kg m^2 (spin), ``steered`` and ``driven`` flags."""
    hardpoint: tuple
    rest_length: float = 0.3
    radius: float = 0.35
    stiffness: float = 30000.0
    damping: float = 3000.0
    friction: float = 1.0
    inertia: float = 1.2
    steered: bool = False
    driven: bool = False


def _clip(f_long, f_lat, limit):
    """Clip a tyre force to the friction circle of radius ``limit``."""
    mag = math.hypot(f_long, f_lat)
    if mag > limit:
        return f_long * limit / mag, f_lat * limit / mag
    return f_long, f_lat


class RaycastVehicle:
    """A chassis body of ``world`` carried by ray-cast ``wheels`` (see the module docstring).

    >>> car = RaycastVehicle(world, chassis, [Wheel((1.2, 0.8, -0.2), steered=True), ...])
    >>> car.steering, car.engine_torque, car.brake_torque = 0.2, 300.0, 0.0
    >>> car.update(); world.step()

    State (read after `update`): ``wheel_omega (W,)`` rad/s spin, ``wheel_compression (W,)`` m,
    ``wheel_in_contact (W,) bool``, ``wheel_contact_point (W, 3)`` m, ``wheel_suspension_force (W,)`` N,
    ``wheel_tyre_force (W, 2)`` N (longitudinal, lateral).

    Checkpoints: the vehicle registers with ``world.checkpoint_parts``, so ``world.save()`` /
    ``world.restore()`` carry its wheel spin and inputs (`save` / `restore` here do it alone)."""

    def __init__(self, world, chassis: int, wheels: list[Wheel], *, queries: WorldQueries | None = None):
        m = world.model
        if not isinstance(chassis, (int, np.integer)) or not 0 <= chassis < m.body_count:
            raise ValueError(f"chassis must be a body index in [0, {m.body_count - 1}]; got {chassis!r}")
        if m.body_type[chassis] != 0:
            raise ValueError("chassis must be a dynamic body")
        if len(wheels) < 1:
            raise ValueError("wheels must hold at least one Wheel")
        for k, w in enumerate(wheels):
            hp = np.asarray(w.hardpoint, dtype=np.float64).reshape(-1)
            if hp.shape != (3,) or not np.all(np.isfinite(hp)):
                raise ValueError(f"wheels[{k}].hardpoint must be 3 finite numbers; got {w.hardpoint!r}")
            for name in ("rest_length", "radius", "stiffness", "inertia"):
                positive_scalar(getattr(w, name), f"wheels[{k}].{name}")
            for name in ("damping", "friction"):
                v = float(getattr(w, name))
                if not math.isfinite(v) or v < 0:
                    raise ValueError(f"wheels[{k}].{name} must be >= 0; got {v!r}")
        self.world, self.chassis, self.wheels = world, int(chassis), list(wheels)
        self.queries = queries if queries is not None else WorldQueries(world)
        nw = len(wheels)
        self.steering = 0.0          # rad, bicycle-model steering angle (+ = left); wheels use Ackermann
        self.engine_torque = 0.0     # N m on each driven wheel
        self.brake_torque = 0.0      # N m on every wheel
        self.wheel_omega = np.zeros(nw)
        self.wheel_compression = np.zeros(nw)
        self.wheel_in_contact = np.zeros(nw, bool)
        self.wheel_contact_point = np.zeros((nw, 3))
        self.wheel_suspension_force = np.zeros(nw)
        self.wheel_tyre_force = np.zeros((nw, 2))
        self._hard = np.array([np.asarray(w.hardpoint, dtype=np.float64) for w in wheels])
        rear = [h[0] for h, w in zip(self._hard, wheels) if not w.steered]
        front = [h[0] for h, w in zip(self._hard, wheels) if w.steered]
        self._rear_x = float(np.mean(rear)) if rear else 0.0
        self._wheelbase = float(np.mean(front)) - self._rear_x if front else 1.0
        if front and self._wheelbase <= 0:
            raise ValueError("steered wheels must sit ahead (+x) of the unsteered ones (wheelbase > 0)")
        # the world's checkpoint (RigidWorld.save / restore) carries this vehicle's state too
        parts = getattr(world, "checkpoint_parts", None)
        if parts is not None:
            parts.append(self)

    _STATE = ("wheel_omega", "wheel_compression", "wheel_in_contact", "wheel_contact_point",
              "wheel_suspension_force", "wheel_tyre_force")
    _INPUTS = ("steering", "engine_torque", "brake_torque")

    def save(self) -> dict:
        """Checkpoint of the state that carries over steps: wheel spin (the only integrated quantity),
        the last update's wheel outputs and the driver's inputs (steering, engine and brake torque)."""
        cp = {name: getattr(self, name).copy() for name in self._STATE}
        cp.update({name: float(getattr(self, name)) for name in self._INPUTS})
        return cp

    def restore(self, checkpoint: dict) -> None:
        """Continue bit for bit from `save` (the world restores its own state: `RigidWorld.restore`)."""
        for name in self._STATE:
            getattr(self, name)[...] = checkpoint[name]
        for name in self._INPUTS:
            setattr(self, name, checkpoint[name])

    def update(self) -> None:
        """Wheel rays, suspension and tyre forces for the next ``world.step()`` (see the module docstring)."""
        w_, st = self.world, self.world.state
        dt = w_.dt
        b = self.chassis
        q = st.body_q[b]
        x, R = q[:3], quat_to_mat3(np.ascontiguousarray(q[3:]))
        omega, v = st.body_qd[b, :3], st.body_qd[b, 3:]
        up, fwd0 = R[:, 2], R[:, 0]
        m_q = self.world.model.body_mass[b] / len(self.wheels)
        force = np.zeros(3)
        torque = np.zeros(3)
        self.queries.refresh()
        for k, wh in enumerate(self.wheels):
            hp = x + R @ self._hard[k]
            reach = wh.rest_length + wh.radius
            hit = None
            for h in self.queries.ray_cast_all(hp, -up * reach):
                if h.body != b:
                    hit = h
                    break
            self.wheel_in_contact[k] = hit is not None
            if hit is None:
                self.wheel_compression[k] = 0.0
                self.wheel_suspension_force[k] = 0.0
                self.wheel_tyre_force[k] = 0.0
                self.wheel_omega[k] = self._spin_free(k, wh, dt)
                continue
            c = reach - hit.distance
            v_hp = v + np.cross(omega, hp - x)
            fs = max(0.0, wh.stiffness * c + wh.damping * float(v_hp @ -up))
            # tyre frame in the ground plane
            n = hit.normal
            heading = fwd0
            if wh.steered and self.steering != 0.0:
                # Ackermann geometry: every steered wheel points square to the turn centre on the rear axle
                # line at R = wheelbase / tan(steering) (the bicycle model's centre)
                turn_r = self._wheelbase / math.tan(self.steering)
                ang = math.atan((self._hard[k, 0] - self._rear_x) / (turn_r - self._hard[k, 1]))
                cs, sn = math.cos(ang), math.sin(ang)
                heading = cs * fwd0 + sn * np.cross(up, fwd0)
            f = heading - (heading @ n) * n
            f /= np.linalg.norm(f)
            lat = np.cross(n, f)
            p = hit.point
            v_c = v + np.cross(omega, p - x)
            # wheel spin after this step's engine and brake torques alone
            om_b = self._spin_free(k, wh, dt)
            s_long = float(v_c @ f) - om_b * wh.radius
            s_lat = float(v_c @ lat)
            f_lat = -s_lat * m_q / dt
            limit = wh.friction * fs
            locked = False
            if om_b == 0.0 and self.brake_torque > 0.0:
                # the brake holds the wheel if it can resist the (friction-clipped) locked-wheel force
                f_long, f_lat_l = _clip(-s_long * m_q / dt, f_lat, limit)
                locked = abs(f_long) * wh.radius <= self.brake_torque
                if locked:
                    f_lat = f_lat_l
            if not locked:
                f_long, f_lat = _clip(-s_long / (dt * (1.0 / m_q + wh.radius ** 2 / wh.inertia)), f_lat, limit)
            F = fs * hit.normal + f_long * f + f_lat * lat
            force += F
            torque += np.cross(p - x, F)
            self.wheel_compression[k] = c
            self.wheel_contact_point[k] = p
            self.wheel_suspension_force[k] = fs
            self.wheel_tyre_force[k] = (f_long, f_lat)
            self.wheel_omega[k] = 0.0 if locked else om_b - dt / wh.inertia * f_long * wh.radius
        w_.control.body_force[b] = force
        w_.control.body_torque[b] = torque
        if not st.body_awake[b]:
            w_.wake(b)

    def _spin_free(self, k, wh, dt):
        """Spin after dt under the engine torque, then the brake (towards zero, never past it)."""
        drive = self.engine_torque if wh.driven else 0.0
        om = self.wheel_omega[k] + dt / wh.inertia * drive
        dbrake = dt / wh.inertia * max(0.0, self.brake_torque)
        return math.copysign(max(0.0, abs(om) - dbrake), om)
