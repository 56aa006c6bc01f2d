"""Rigid bodies in a GridFluid: moving shape rows push the fluid, pressure pushes bodies back."""

from types import SimpleNamespace

import numpy as np
import pytest

from inertia.fluids.grid import GridFluid
from inertia.model import ModelBuilder


def _rigid(builder):
    model = builder.finalize()
    return SimpleNamespace(model=model, state=model.state())


def test_translating_body_pushes_fluid_divergence_free_and_covered_faces_move_with_it():
    # a kinematic sphere moving at v through fluid at rest: after the projection the weighted
    # divergence is at the solver tolerance and every face fully inside the body carries the
    # body's rigid velocity v + w x r (here with a spin about z as well)
    b = ModelBuilder(gravity=(0, 0, 0))
    v, w = np.array([0.4, -0.1, 0.2]), np.array([0.0, 0.0, 1.5])
    body = b.add_body(position=(0.5, 0.5, 0.5), linear_velocity=v, angular_velocity=w,
                      body_type="kinematic")
    b.add_sphere(body, radius=0.22)
    rigid = _rigid(b)
    f = GridFluid((16, 16, 16), 1.0 / 16, tolerance=1e-8)
    f.bind_rigid(rigid)
    f.step(0.01)
    div = f.measure_divergence()
    rhs_scale = np.max(np.abs(v)) / f.grid.cell_size
    assert np.max(np.abs(div)) < 1e-5 * rhs_scale
    c = rigid.state.body_q[body, :3]
    checked = 0
    for a, (vel, frac) in enumerate(zip((f.u, f.v, f.w), f.face_fractions)):
        pts = f.grid.face_positions(a).reshape(frac.shape + (3,))
        inside = np.linalg.norm(pts - c, axis=-1) < 0.22 - f.grid.cell_size
        assert np.all(frac[inside] == 0.0)
        r = pts[inside] - c
        expect = v[a] + np.cross(w, r)[:, a]
        np.testing.assert_allclose(vel[inside], expect, rtol=0, atol=1e-12)
        checked += inside.sum()
    assert checked > 100
    # a static body leaves the fluid at rest and is not pushed
    assert np.all(np.isfinite(f.body_force))


@pytest.mark.parametrize("shape", ["box", "sphere"])
def test_buoyancy_on_submerged_fixed_body_is_rho_g_v(shape):
    # closed tank of fluid at rest under gravity: projection gives the hydrostatic pressure
    # p = rho g (z_top - z); the pressure force on a fully submerged body is Archimedes' rho g V
    # upward, with no sideways force and no torque about its centre.
    # The force equals rho g V_grid to the pressure tolerance, V_grid the cut-cell volume (closed
    # share of the z faces times h^3); V_grid differs from V by the face fractions' linear fit of the
    # signed distance: box (faces on cell centres, corners cut) 1.1 % measured, sphere (r = 4.4 h)
    # 2.2 % measured (chords of the linear fit lie inside a convex body: V_grid < V, O(h^2)).
    rho, g, h = 1000.0, 9.81, 1.0 / 20
    b = ModelBuilder(gravity=(0, 0, -g))
    body = b.add_body(position=(0.5, 0.5, 0.475), body_type="kinematic")
    if shape == "box":
        he = np.array([0.175, 0.125, 0.1])   # faces on cell centres
        b.add_box(body, half_extents=he)
        volume = 8 * np.prod(he)
        tol = 0.015
    else:
        r = 0.22
        b.add_sphere(body, radius=r)
        volume = 4.0 / 3.0 * np.pi * r ** 3
        tol = 0.03
    rigid = _rigid(b)
    f = GridFluid((20, 20, 20), h, tolerance=1e-10, body_acceleration=(0, 0, -g),
                  fluid_density=rho)
    f.bind_rigid(rigid)
    for _ in range(3):
        f.step(0.01)
    F, T = f.body_force[body], f.body_torque[body]
    expect = rho * g * volume
    # the cut-cell solid volume the grid sees: closed share of the z faces times h^3
    discrete = rho * g * np.sum(1.0 - f.face_fractions[2][:, :, 1:-1]) * h ** 3
    assert abs(F[2] - discrete) < 1e-6 * discrete, (F, discrete)
    assert abs(F[2] - expect) < tol * expect, (F, expect)
    assert np.all(np.abs(F[:2]) < 1e-6 * expect)
    assert np.all(np.abs(T) < 1e-6 * expect * 0.2)


def test_dynamic_body_receives_buoyancy_impulse():
    # a dynamic sphere of density 500 held at rest in a hydrostatic fluid gains dv = rho g V dt / m
    # upward from one step's pressure (its own gravity is the rigid stage's, not applied here)
    rho, g, h, dt = 1000.0, 9.81, 1.0 / 16, 0.005
    b = ModelBuilder(gravity=(0, 0, -g))
    body = b.add_body(position=(0.5, 0.5, 0.5))
    b.add_sphere(body, radius=0.2, density=500.0)
    rigid = _rigid(b)
    f = GridFluid((16, 16, 16), h, tolerance=1e-10, body_acceleration=(0, 0, -g), fluid_density=rho)
    f.bind_rigid(rigid)
    f.step(dt)
    m = rigid.model.body_mass[body]
    dv = rigid.state.body_qd[body, 3:]
    np.testing.assert_allclose(dv[2], f.body_force[body, 2] * dt / m, rtol=1e-12)
    assert dv[2] > 0
    assert abs(f.body_force[body, 2] / (rho * g * 4 / 3 * np.pi * 0.2 ** 3) - 1) < 0.05


def test_bind_rigid_needs_3d():
    b = ModelBuilder()
    b.add_sphere(b.add_body(), radius=0.1)
    with pytest.raises(ValueError, match="3-D"):
        GridFluid((8, 8), 0.1).bind_rigid(_rigid(b))


# ----------------------------------------------------------------------------- viscous stress
PERIODIC_XZ = {"x-": "periodic", "x+": "periodic", "z-": "periodic", "z+": "periodic"}


def test_viscous_drag_on_a_sliding_plate_is_mu_u_over_h():
    # Plane Couette flow between the no-slip wall y = 0 and a kinematic plate body (box row)
    # sliding at U, its lower face at y = H off the grid lines. Closed form: the shear stress on
    # the plate is -mu U / H (mu = rho nu), so body_force_x = -rho nu U / H times the plate area in
    # the periodic box. Reached 1e-9 relative after t = 4 (the start-up transient decays as
    # exp(-pi^2 nu t / H^2) ~ 1e-19); bound 2 %. Pressure is uniform: no normal force or torque.
    U, nu, H, rho, h = 0.5, 0.2, 0.43, 1000.0, 1.0 / 16
    nx, ny, nz = 4, int(np.ceil(H / h)) + 2, 4
    b = ModelBuilder(gravity=(0, 0, 0))
    body = b.add_body(position=(0.5 * nx * h, H + 1.0, 0.5 * nz * h), linear_velocity=(U, 0, 0),
                      body_type="kinematic")
    b.add_box(body, half_extents=(10.0, 1.0, 10.0))
    rigid = _rigid(b)
    f = GridFluid((nx, ny, nz), h, boundaries=PERIODIC_XZ, viscosity=nu, scalars=(), fluid_density=rho)
    f.bind_rigid(rigid)
    for _ in range(40):
        f.step(0.1)
    y = (np.arange(ny) + 0.5) * h
    fluid = y < H
    np.testing.assert_allclose(f.u[1, fluid, 1], U * y[fluid] / H, rtol=0, atol=0.01 * U)
    area = nx * h * nz * h
    assert f.body_force[body, 0] == pytest.approx(-rho * nu * U / H * area, rel=0.02)
    assert np.all(np.abs(f.body_force[body, 1:]) < 1e-9 * rho * nu * U / H * area)
    # slip=True: the plate no longer drags the fluid (pressure only)
    g = GridFluid((nx, ny, nz), h, boundaries=PERIODIC_XZ, viscosity=nu, scalars=(), fluid_density=rho)
    g.bind_rigid(rigid, slip=True)
    g.step(0.1)
    assert np.all(g.u[:, fluid, :] == 0.0) and np.all(g.body_force == 0.0)


def test_viscous_exchange_conserves_fluid_plus_body_momentum():
    # A free (dynamic) plate sliding through fluid at rest in a fully periodic box: the viscous
    # stress is the only force (u = u(y): advection is exact along x, the velocity stays
    # divergence-free, pressure stays 0). Whatever x-momentum the viscous solve moves into the
    # fluid nodes next to the plate the plate loses (Newton's third law, summed link by link):
    # fluid + body momentum constant to round-off (measured 7e-18 of 0.05), while the plate
    # loses 22 % of its own.
    U, nu, rho, m, h = 1.0, 0.05, 1.0, 0.05, 1.0 / 16
    n = (4, 16, 4)
    lo, hi = 0.3 + 0.3 * h, 0.6 + 0.3 * h    # the plate's y-extent, off the grid lines
    b = ModelBuilder(gravity=(0, 0, 0))
    body = b.add_body(position=(0.5 * n[0] * h, 0.5 * (lo + hi), 0.5 * n[2] * h),
                      linear_velocity=(U, 0, 0), mass=m, inertia=(1.0, 1.0, 1.0))
    b.add_box(body, half_extents=(10.0, 0.5 * (hi - lo), 10.0))
    rigid = _rigid(b)
    f = GridFluid(n, h, boundaries={s: "periodic" for s in ("x-", "x+", "y-", "y+", "z-", "z+")},
                  viscosity=nu, scalars=(), fluid_density=rho)
    f.bind_rigid(rigid)
    y = (np.arange(n[1]) + 0.5) * h
    in_fluid = (y < lo) | (y > hi)

    def momentum():
        fluid = rho * h**3 * f.u[:-1][:, in_fluid, :].sum()   # (face n duplicates face 0)
        return fluid, m * rigid.state.body_qd[body, 3]        # body_qd = (angular, linear)
    p0 = sum(momentum())
    for _ in range(10):
        f.step(0.02)
        assert abs(sum(momentum()) - p0) < 1e-12 * p0
    assert momentum()[1] < 0.8 * p0
