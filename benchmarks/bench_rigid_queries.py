"""Free rigid bodies and convex queries; every figure is a ratio to a baseline measured in the same run.

    python benchmarks/bench_rigid_queries.py            # 200 000 bodies, 20 000 query pairs
    python benchmarks/bench_rigid_queries.py --quick    # 20 000 bodies, 2 000 pairs

1. Free-body derivative (Witkin-Baraff x, q, P, L) over B bodies: the Numba kernel against the same maths in
   vectorised NumPy, and its effective bandwidth against the machine's copy bandwidth (it reads 13 + 12
   doubles and writes 13 per body).  Also one rk4 step of FreeBodies per body.
2. Convex queries, box-box pairs with random poses (about half overlapping): ``shape_distance`` (GJK, EPA when
   overlapping) per pair in a batched Numba loop and called one by one from Python, against PyBullet's
   ``getClosestPoints`` between the same two boxes (one call per pair, Bullet's GJK/EPA behind a Python
   call), if PyBullet is installed.  The distances are compared (they must agree to 1e-4 m: Bullet keeps
   a collision margin).

Timings are medians over repeats after a warm-up (Numba compilation excluded).
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np
from numba import njit

sys.path.insert(0, os.path.dirname(__file__))
from _common import best_time, copy_bandwidth  # noqa: E402

from inertia import math as im  # noqa: E402
from inertia.geometry import convex as C  # noqa: E402
from inertia.rigid.free_body import FreeBodies, free_body_derivative  # noqa: E402
from inertia.simulation import Simulation  # noqa: E402


def numpy_derivative(pose, mom, inv_mass, inv_inertia, force, torque, gravity, out_pose, out_mom):
    """The free-body derivative in vectorised NumPy (the same maths as the kernel)."""
    q = pose[:, 3:] / np.linalg.norm(pose[:, 3:], axis=1, keepdims=True)
    w, x, y, z = q.T
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
    body = inv_inertia * np.einsum("bji,bj->bi", r, mom[:, :3])
    omega = np.einsum("bij,bj->bi", r, body)
    out_pose[:, :3] = mom[:, 3:] * inv_mass[:, None]
    pw, px, py, pz = pose[:, 3:].T
    ox, oy, oz = omega.T
    out_pose[:, 3] = 0.5 * (-ox * px - oy * py - oz * pz)
    out_pose[:, 4] = 0.5 * (ox * pw + oy * pz - oz * py)
    out_pose[:, 5] = 0.5 * (-ox * pz + oy * pw + oz * px)
    out_pose[:, 6] = 0.5 * (ox * py - oy * px + oz * pw)
    out_mom[:, :3] = torque
    out_mom[:, 3:] = gravity / inv_mass[:, None] + force


def bench_free_bodies(n):
    rng = np.random.default_rng(0)
    bodies = FreeBodies(rng.uniform(1, 2, n), np.sort(rng.uniform(0.5, 1, (n, 3)), axis=1),
                        orientations=rng.normal(size=(n, 4)), velocities=rng.normal(size=(n, 3)),
                        angular_velocities=rng.normal(size=(n, 3)), gravity=(0, 0, -9.81))
    out = np.zeros_like(bodies.state)
    args = (bodies.body_inv_mass, bodies.body_inv_inertia, bodies.body_force, bodies.body_torque, bodies.gravity)
    t_kernel = best_time(lambda: free_body_derivative(bodies.state, *args, out))
    t_serial = best_time(lambda: free_body_derivative.serial(bodies.state, *args, out))
    out_pose = np.zeros((n, 7))
    out_mom = np.zeros((n, 6))
    t_numpy = best_time(lambda: numpy_derivative(bodies.body_pose, bodies.body_momentum, *args, out_pose, out_mom))
    ref = np.concatenate([out_pose.ravel(), out_mom.ravel()])
    assert np.allclose(out, ref, rtol=1e-12, atol=1e-12), "kernel and NumPy disagree"
    bandwidth = copy_bandwidth()
    moved = n * 8 * (13 + 12 + 13)
    sim = Simulation(bodies, "rk4", dt=1e-3)
    sim.step()
    t_step = best_time(sim.step, repeat=5)
    print(f"free-body derivative, {n} bodies: serial kernel {t_serial * 1e3:.2f} ms "
          f"({t_numpy / t_serial:.1f}x NumPy); parallel:")
    print(f"free-body derivative, {n} bodies: kernel {t_kernel * 1e3:.2f} ms, NumPy {t_numpy * 1e3:.2f} ms "
          f"-> {t_numpy / t_kernel:.1f}x faster; {moved / t_kernel / 1e9:.2f} GB/s = "
          f"{moved / t_kernel / bandwidth:.2f} of copy bandwidth ({bandwidth / 1e9:.1f} GB/s)")
    print(f"FreeBodies rk4 step, {n} bodies: {t_step * 1e3:.2f} ms = {t_step / n * 1e9:.0f} ns per body "
          f"({t_step / t_kernel:.1f} derivative evaluations' worth)")


@njit(cache=True)
def batched_box_distances(half_a, half_b, poses_a, poses_b, verts, out):
    pa = np.zeros(4)
    pb = np.zeros(4)
    for i in range(out.shape[0]):
        pa[:3] = half_a[i]
        pb[:3] = half_b[i]
        d, wa, wb, n = C.shape_distance(1, pa, poses_a[i], 0, 0, 1, pb, poses_b[i], 0, 0, verts)
        out[i] = d


def minkowski_signed_distance(pts_a, pts_b):
    """Exact signed distance of two convex polytopes from Qhull's hull of all a_i - b_j: outside, the distance
    from the origin to the nearest hull triangle; inside, minus the distance to the nearest facet plane."""
    from scipy.spatial import ConvexHull
    diff = (pts_a[:, None, :] - pts_b[None, :, :]).reshape(-1, 3)
    hull = ConvexHull(diff)
    if np.all(hull.equations[:, 3] < 0):
        return hull.equations[:, 3].max()
    best = np.inf
    for tri in hull.simplices:
        a, b, c = diff[tri]
        lam = C._closest_on_triangle(a, b, c)
        best = min(best, np.linalg.norm(lam[0] * a + lam[1] * b + lam[2] * c))
    return best


def bench_queries(pairs):
    rng = np.random.default_rng(1)
    half_a = rng.uniform(0.2, 0.8, (pairs, 3))
    half_b = rng.uniform(0.2, 0.8, (pairs, 3))
    poses_a = np.zeros((pairs, 7))
    poses_b = np.zeros((pairs, 7))
    for i in range(pairs):
        qa, qb = rng.normal(size=4), rng.normal(size=4)
        poses_a[i, 3:] = qa / np.linalg.norm(qa)
        poses_b[i, 3:] = qb / np.linalg.norm(qb)
        poses_b[i, :3] = rng.normal(size=3) * 0.8
    verts = np.zeros((1, 3))
    out = np.zeros(pairs)
    t_batch = best_time(lambda: batched_box_distances(half_a, half_b, poses_a, poses_b, verts, out), repeat=5)
    overlapping = int(np.sum(out < 0))

    def one_by_one():
        for i in range(pairs):
            C.shape_distance(1, np.r_[half_a[i], 0.0], poses_a[i], 0, 0, 1, np.r_[half_b[i], 0.0], poses_b[i], 0, 0,
                             verts)
    t_python = best_time(one_by_one, repeat=3, warmup=1)
    print(f"box-box shape_distance, {pairs} pairs ({overlapping} overlapping -> EPA): batched Numba "
          f"{t_batch / pairs * 1e6:.2f} us/pair, one call per pair from Python {t_python / pairs * 1e6:.2f} us/pair")
    try:
        import pybullet as p
    except ImportError:
        print("PyBullet not installed: no peer comparison (pip install pybullet)")
        return
    client = p.connect(p.DIRECT)
    bodies = []
    for i in range(pairs):
        sa = p.createCollisionShape(p.GEOM_BOX, halfExtents=half_a[i].tolist(), physicsClientId=client)
        sb = p.createCollisionShape(p.GEOM_BOX, halfExtents=half_b[i].tolist(), physicsClientId=client)
        qa = poses_a[i, [4, 5, 6, 3]].tolist()
        qb = poses_b[i, [4, 5, 6, 3]].tolist()
        ba = p.createMultiBody(0, sa, basePosition=poses_a[i, :3].tolist(), baseOrientation=qa,
                               physicsClientId=client)
        bb = p.createMultiBody(0, sb, basePosition=poses_b[i, :3].tolist(), baseOrientation=qb,
                               physicsClientId=client)
        bodies.append((ba, bb))
    bullet = np.zeros(pairs)

    def bullet_queries():
        for i, (ba, bb) in enumerate(bodies):
            pts = p.getClosestPoints(ba, bb, 10.0, physicsClientId=client)
            bullet[i] = min(c[8] for c in pts) if pts else np.inf
    t_bullet = best_time(bullet_queries, repeat=3, warmup=1)
    agree = np.abs(bullet - out)
    print(f"PyBullet getClosestPoints: {t_bullet / pairs * 1e6:.2f} us/pair -> ours batched "
          f"{t_bullet / t_batch:.1f}x faster, one-by-one {t_bullet / t_python:.1f}x; "
          f"max |d_ours - d_bullet| = {agree.max():.2e} m (median {np.median(agree):.1e})")
    # who is right where they disagree most: the exact signed distance from the hull of A - B
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    worst = np.argsort(agree)[-5:]
    err_ours, err_bullet = [], []
    for i in worst:
        wa = np.array([im.transform_point(poses_a[i], c) for c in corners * half_a[i]])
        wb = np.array([im.transform_point(poses_b[i], c) for c in corners * half_b[i]])
        exact = minkowski_signed_distance(wa, wb)
        err_ours.append(abs(out[i] - exact))
        err_bullet.append(abs(bullet[i] - exact))
    print(f"  on the 5 pairs where they differ most, error against the exact Minkowski-hull distance: ours "
          f"{max(err_ours):.1e} m, PyBullet {max(err_bullet):.1e} m")
    p.disconnect(client)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    args = parser.parse_args()
    t0 = time.perf_counter()
    bench_free_bodies(20_000 if args.quick else 200_000)
    bench_queries(2_000 if args.quick else 20_000)
    print(f"(total {time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
