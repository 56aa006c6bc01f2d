"""Rigid poses of colliders: rotations, and kinematic (scripted) motion over time.

A collider is built in its *rest pose* (the coordinates given to its constructor). A
``Motion`` moves it rigidly: at time t the rest point ``X`` is at

    x(t) = p(t) + R(t) (X - c)

where ``c`` is the collider's reference point (its centre; a plane's ``point``), ``p(t)`` the
world position of that reference point and ``R(t)`` a rotation relative to the rest
orientation. Velocities of the collider material are the time derivatives of ``x(t)``; for a
step from t0 to t1 the collision stage uses the average ``(x(t1) - x(t0)) / (t1 - t0)``.

References
----------
- Shoemake, K. (1985), "Animating rotation with quaternion curves", SIGGRAPH: slerp, used
  between rotation keyframes.
- Rodrigues' rotation formula for the axis-angle exponential map.

Limitations
-----------
- Motions are rigid (no scaling or deformation).
- Keyframes interpolate positions linearly and rotations by slerp (2-D: linearly in angle);
  outside the keyframe range the first or last pose is held.
- Point velocities from ``Motion.velocity`` are central finite differences of the pose.
"""

from __future__ import annotations

import numpy as np

from ..math import quat_to_mat3

__all__ = ["Motion", "as_rotation", "rotation_log", "rotation_exp"]


# --- rotations -------------------------------------------------------------------------------
def rotation_exp(rotvec) -> np.ndarray:
    """3x3 rotation matrix of the rotation vector ``axis * angle`` (Rodrigues)."""
    w = np.asarray(rotvec, dtype=np.float64).reshape(3)
    angle = float(np.linalg.norm(w))
    if angle < 1e-300:
        return np.eye(3)
    k = w / angle
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + np.sin(angle) * kx + (1.0 - np.cos(angle)) * (kx @ kx)


def rotation_log(r) -> np.ndarray:
    """Rotation vector (axis * angle, angle in [0, pi]) of a 3x3 rotation matrix."""
    r = np.asarray(r, dtype=np.float64)
    cos_angle = np.clip((np.trace(r) - 1.0) * 0.5, -1.0, 1.0)
    angle = float(np.arccos(cos_angle))
    skew = np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]])
    if angle < 1e-7:
        return 0.5 * skew  # sin(angle) ~ angle
    if np.pi - angle > 1e-6:
        return skew * (angle / (2.0 * np.sin(angle)))
    # near pi: axis from the symmetric part, R = 2 k k^T - I
    k = np.sqrt(np.maximum((np.diag(r) + 1.0) * 0.5, 0.0))
    i = int(np.argmax(k))
    k[(i + 1) % 3] = np.copysign(k[(i + 1) % 3], r[i, (i + 1) % 3] + r[(i + 1) % 3, i])
    k[(i + 2) % 3] = np.copysign(k[(i + 2) % 3], r[i, (i + 2) % 3] + r[(i + 2) % 3, i])
    return k / np.linalg.norm(k) * angle


def _quaternion_matrix(q) -> np.ndarray:
    return quat_to_mat3(np.ascontiguousarray(q / np.linalg.norm(q), dtype=np.float64))


def as_rotation(value, dim: int, name: str = "rotation") -> np.ndarray:
    """Return `value` as a 3x3 rotation matrix.

    2-D: an angle in radians (about +z) or a 2x2 rotation matrix.
    3-D: a 3x3 rotation matrix, a unit quaternion ``(w, x, y, z)`` or a rotation vector
    ``axis * angle`` (3 components). ``None`` is the identity.
    """
    if value is None:
        return np.eye(3)
    arr = np.asarray(value, dtype=np.float64)
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite; got {arr.tolist()}")
    if dim == 2:
        if arr.ndim == 0 or arr.size == 1:
            a = float(arr.reshape(-1)[0])
            c, s = np.cos(a), np.sin(a)
            return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        if arr.shape == (2, 2):
            out = np.eye(3)
            out[:2, :2] = arr
            return _check_orthonormal(out, name)
        raise ValueError(f"{name} in 2-D must be an angle in radians or a 2x2 rotation matrix; "
                         f"got shape {arr.shape}")
    if arr.shape == (3, 3):
        return _check_orthonormal(arr.copy(), name)
    if arr.shape == (4,):
        if np.linalg.norm(arr) < 1e-12:
            raise ValueError(f"{name} quaternion (w, x, y, z) must be non-zero; got {arr.tolist()}")
        return _quaternion_matrix(arr)
    if arr.shape == (3,):
        return rotation_exp(arr)
    raise ValueError(f"{name} in 3-D must be a 3x3 matrix, a quaternion (w, x, y, z) or a rotation "
                     f"vector (3 components); got shape {arr.shape}")


def _check_orthonormal(r, name):
    if not np.allclose(r @ r.T, np.eye(3), atol=1e-6) or np.linalg.det(r) < 0:
        raise ValueError(f"{name} must be a proper rotation matrix (orthonormal, det +1)")
    return r


def _slerp_matrix(r0, r1, s):
    return r0 @ rotation_exp(s * rotation_log(r0.T @ r1))


# --- kinematic motion ------------------------------------------------------------------------
class Motion:
    """Prescribed rigid motion of a collider.

    Parameters
    ----------
    position : callable t -> (D,), optional
        World position of the collider's reference point at time t (seconds). Default: the rest
        position.
    rotation : callable t -> rotation, optional
        Rotation at time t relative to the rest orientation, about the reference point:
        2-D an angle in radians; 3-D a 3x3 matrix, quaternion (w, x, y, z) or rotation vector.
        Default: no rotation.

    Use ``Motion.keyframes(times, positions=..., rotations=...)`` for key-framed motion.
    Example: a paddle moving along x at 2 m/s: ``Motion(position=lambda t: (2.0 * t, 0.0, 0.5))``.
    """

    def __init__(self, position=None, rotation=None):
        if position is not None and not callable(position):
            raise ValueError(f"position must be a callable t -> (D,) array; got {type(position).__name__}")
        if rotation is not None and not callable(rotation):
            raise ValueError(f"rotation must be a callable t -> rotation; got {type(rotation).__name__}")
        self._position = position
        self._rotation = rotation
        self.rotates = rotation is not None

    @classmethod
    def keyframes(cls, times, positions=None, rotations=None) -> "Motion":
        """Piecewise motion through keyframes.

        times : (K,) increasing seconds. positions : (K, D) reference-point positions.
        rotations : (K,) angles (2-D) or (K, 3, 3) / (K, 4) quaternions / (K, 3) rotation
        vectors (3-D), relative to the rest orientation. Positions are interpolated linearly,
        rotations by slerp; the first/last key is held outside [times[0], times[-1]].
        """
        times = np.asarray(times, dtype=np.float64).reshape(-1)
        if times.size < 1 or not np.all(np.isfinite(times)) or np.any(np.diff(times) <= 0):
            raise ValueError(f"times must be a non-empty, finite, strictly increasing sequence; got {times.tolist()}")
        key_positions = None
        if positions is not None:
            key_positions = np.asarray(positions, dtype=np.float64)
            if key_positions.ndim != 2 or key_positions.shape[0] != times.size \
                    or key_positions.shape[1] not in (2, 3) or not np.all(np.isfinite(key_positions)):
                raise ValueError(f"positions must be a finite ({times.size}, D) array with D in (2, 3); "
                                 f"got shape {key_positions.shape}")
        key_rotations = None
        if rotations is not None:
            rot = np.asarray(rotations, dtype=np.float64)
            if rot.shape[0] != times.size:
                raise ValueError(f"rotations must have one entry per key time ({times.size}); got {rot.shape[0]}")
            dim = 2 if rot.ndim == 1 else 3
            key_rotations = np.stack([as_rotation(r, dim, "rotations") for r in rot])

        def position(t):
            return np.array([np.interp(t, times, key_positions[:, c]) for c in range(key_positions.shape[1])])

        def rotation(t):
            if t <= times[0]:
                return key_rotations[0]
            if t >= times[-1]:
                return key_rotations[-1]
            k = int(np.searchsorted(times, t, side="right")) - 1
            s = (t - times[k]) / (times[k + 1] - times[k])
            return _slerp_matrix(key_rotations[k], key_rotations[k + 1], s)

        return cls(position if key_positions is not None else None,
                   rotation if key_rotations is not None else None)

    def pose(self, t: float, dim: int, rest_point: np.ndarray):
        """(p, R): world position (3,) of the reference point and rotation (3, 3) at time t."""
        p = rest_point.copy()
        if self._position is not None:
            value = np.asarray(self._position(float(t)), dtype=np.float64).reshape(-1)
            if value.shape[0] != dim or not np.all(np.isfinite(value)):
                raise ValueError(f"motion position(t) must return {dim} finite numbers; got {value.tolist()} at t={t}")
            p[:dim] = value
        r = np.eye(3)
        if self._rotation is not None:
            r = as_rotation(self._rotation(float(t)), dim, "motion rotation(t)")
        return p, r
