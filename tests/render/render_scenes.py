"""Small scenes shared by the render tests, the golden images and the benchmark."""

from __future__ import annotations

import numpy as np


def lattice_3d(n_side: int = 6, spacing: float = 0.25, height: float = 0.3):
    """A cube of particles above the ground: positions (N, 3), radii (N,), groups (N,)."""
    g = (np.arange(n_side) - (n_side - 1) / 2) * spacing
    x, y, z = np.meshgrid(g, g, g + (n_side - 1) / 2 * spacing + height, indexing="ij")
    positions = np.column_stack([x.ravel(), y.ravel(), z.ravel()])
    k = np.arange(positions.shape[0])
    radius = 0.06 + 0.03 * (k % 3) / 2
    groups = (k % 4).astype(np.int32)
    return positions, radius, groups


def swirl_2d(count: int = 400):
    """A spiral of particles with velocities along it: positions (N, 2), velocities (N, 2)."""
    s = np.linspace(0.0, 1.0, count)
    angle = 6.0 * np.pi * s
    r = 0.2 + 0.8 * s
    positions = np.column_stack([r * np.cos(angle), r * np.sin(angle)])
    velocities = np.column_stack([-np.sin(angle), np.cos(angle)]) * (0.5 + 2.0 * s[:, None])
    return positions, velocities


def random_cloud(count: int, seed: int = 0):
    """``count`` particles in a box above the ground, with random velocities."""
    rng = np.random.default_rng(seed)
    positions = rng.random((count, 3)) * np.array([2.0, 2.0, 1.5]) - np.array([1.0, 1.0, 0.0])
    velocities = rng.normal(size=(count, 3))
    return positions, velocities


def colliders_3d():
    import inertia.colliders as C

    return [
        C.Plane(point=(0.0, 0.0, 0.0), normal=(0.0, 0.0, 1.0)),
        C.Sphere(center=(1.3, 0.4, 0.35), radius=0.35),
        C.Box(center=(1.2, -0.7, 0.2), half_extents=(0.25, 0.2, 0.2), rotation=(np.cos(0.3), 0.0, 0.0, np.sin(0.3))),
        C.Capsule(a=(-1.4, -0.8, 0.15), b=(-1.4, 0.8, 0.15), radius=0.15),
        C.Cylinder(center=(-0.2, 1.4, 0.25), radius=0.2, half_height=0.25),
    ]


def colliders_2d():
    import inertia.colliders as C

    return [
        C.Container(center=(0.0, 0.0), half_extents=(1.3, 1.2)),
        C.Sphere(center=(0.0, 0.0), radius=0.12),
        C.Box(center=(0.8, 0.8), half_extents=(0.2, 0.1), rotation=0.5),
        C.Capsule(a=(-0.9, 0.9), b=(-0.5, 1.0), radius=0.06),
    ]
