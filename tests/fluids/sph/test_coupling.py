"""SPH <-> RigidWorld coupling (inertia.fluids.sph.coupling): boundary bands sampled on the Model's
shape rows, posed from body_q, fluid impulses written back into body_qd.

Scenes are thin 3-D slabs (periodic across a depth of 6 spacings = 3 kernel supports) so that they
stay small; the references are Archimedes' principle and the shape's signed distance.
"""

import numpy as np
import pytest

from inertia.dynamics.particle_coupling import apply_body_impulses

from inertia.fluids.sph import SPHFluid, sample_block
from inertia.fluids.sph import coupling
from inertia.geometry import shapes as S
from inertia.model import ModelBuilder
from inertia.rigid.world import RigidWorld

G = 9.81


def test_shape_signed_distances_against_closed_forms():
    # Points on each shape's surface have distance 0, the centre minus the inradius.
    p = np.array([[0.0, 0.0, 0.0], [0.3, 0.0, 0.0], [0.0, 0.0, 0.5]])
    assert np.allclose(coupling.shape_signed_distance(S.SPHERE, (0.3, 0, 0, 0), p), [-0.3, 0.0, 0.2])
    assert np.allclose(coupling.shape_signed_distance(S.BOX, (0.3, 0.2, 0.5, 0), p), [-0.2, 0.0, 0.0])
    assert np.allclose(coupling.shape_signed_distance(S.CAPSULE, (0.3, 0.2, 0, 0), p), [-0.3, 0.0, 0.0])
    assert np.allclose(coupling.shape_signed_distance(S.CYLINDER, (0.3, 0.5, 0, 0), p), [-0.3, 0.0, 0.0])
    cube = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)], float) * 0.5
    assert np.allclose(coupling.shape_signed_distance(S.CONVEX_HULL, None, np.array([[0, 0, 0], [0.5, 0, 0.2]]),
                                                      cube), [-0.5, 0.0])
    assert np.allclose(coupling.shape_signed_distance(S.PLANE, None, p), [0.0, 0.0, 0.5])
    with pytest.raises(ValueError, match="cannot be sampled"):
        coupling.shape_signed_distance(S.TRIANGLE_MESH, None, p)


def test_apply_body_impulses_closed_form():
    # the one helper every coupled system uses (inertia.dynamics.particle_coupling):
    # dv = J / m and dw = I^-1 L for a box of mass m = rho V and I_zz = m (a^2 + b^2) / 12.
    b = ModelBuilder(gravity=(0, 0, 0))
    body = b.add_body(position=(0, 0, 1))
    b.add_box(body, half_extents=(0.1, 0.2, 0.3), density=500.0)
    static = b.add_body(position=(1, 0, 1), body_type="static")
    b.add_box(static, half_extents=(0.1, 0.1, 0.1))
    model = b.finalize()
    state = model.state()
    m = 500.0 * 0.2 * 0.4 * 0.6
    izz = m * (0.2 ** 2 + 0.4 ** 2) / 12
    apply_body_impulses(model, state, np.array([[1.0, 0, 0], [5.0, 0, 0]]),
                        np.array([[0, 0, 2.0], [0, 0, 3.0]]))
    assert np.allclose(state.body_qd[0], [0, 0, 2.0 / izz, 1.0 / m, 0, 0])
    assert np.all(state.body_qd[1] == 0.0)


def _slab(width, depth, dx, hole=None):
    period = 6 * dx
    x = sample_block((0.0, 0.0, 0.0), (width, period, depth), dx)
    if hole is not None:  # no fluid inside the body's box (centre, half extents in x and z)
        (cx, cz), (hx, hz) = hole
        x = x[~((np.abs(x[:, 0] - cx) < hx) & (np.abs(x[:, 2] - cz) < hz))]
    return x, period


def _tank(builder, width):
    builder.add_plane((0, 0, 1), 0.0)
    builder.add_plane((1, 0, 0), 0.0)
    builder.add_plane((-1, 0, 0), -width)


def test_submerged_body_feels_archimedes_buoyancy():
    # Archimedes: a held, fully submerged box of volume V feels F_z = rho0 g V and, by symmetry,
    # no horizontal force. Kinematic box (6 x 6 x 4 spacings) in a 0.35 m column, dx = 2.5 cm.
    # The force is a difference of the bottom and top pressures (2450 and 1470 Pa), so a few
    # per cent of pressure error (DFSPH compression 1.7x its tolerance below the surface, the
    # staircased band) is ~10 % of the net: measured 0.88 +- 0.05 over 0.5-1.5 s (time average;
    # the instantaneous force rings with the column). Checked: within 20 % of rho0 g V, and
    # the sideways force below 5 % of it.
    dx, width, depth, bw, bh, cz = 0.025, 0.4, 0.35, 0.15, 0.1, 0.15
    x, period = _slab(width, depth, dx, hole=((width / 2, cz), (bw / 2, bh / 2)))
    fluid = SPHFluid(x, spacing=dx, domain=((0, 0, 0), (width, period, depth + 0.1)), periodic=(False, True, False),
                     viscosity=1e-2, xsph=0.05, max_iterations=300)
    b = ModelBuilder(gravity=(0, 0, -G))
    _tank(b, width)
    body = b.add_body(position=(width / 2, period / 2, cz), body_type="kinematic")
    b.add_box(body, half_extents=(bw / 2, period / 2, bh / 2))
    rigid = RigidWorld(b.finalize(), dt=1 / 200, substeps=1, enable_sleep=False)
    forces = []
    while rigid.state.time < 1.5:
        rigid.step()
        fluid.advance(rigid.dt, rigid)
        if rigid.state.time > 0.5:
            forces.append(fluid.body_force[body].copy())
    mean = np.mean(forces, axis=0)
    archimedes = fluid.rest_density * G * bw * period * bh
    assert abs(mean[2] / archimedes - 1.0) < 0.2, mean[2] / archimedes
    assert abs(mean[0]) < 0.05 * archimedes, mean
    assert np.all(rigid.state.body_qd[body] == 0.0)  # kinematic: the fluid does not move it


@pytest.mark.parametrize("relative_density", [0.5, 2.0])
def test_light_box_floats_dense_box_sinks_in_rigid_world(relative_density):
    # A RigidWorld box released with its bottom at the surface: density 2 sinks and rests on the
    # floor plane (rigid contact; bottom within one spacing of z = 0 after 1.2 s, 0.3 m of fall);
    # density 0.5 floats: after 1.2 s its bottom is still above mid-depth and its draft between
    # a quarter and three quarters of its height (Archimedes: half).
    dx, width, depth, bw, bh = 0.025, 0.6, 0.3, 0.2, 0.15
    x, period = _slab(width, depth, dx)
    fluid = SPHFluid(x, spacing=dx, domain=((0, 0, 0), (width, period, depth + 0.3)), periodic=(False, True, False),
                     viscosity=5e-3, xsph=0.05, max_iterations=200)
    b = ModelBuilder(gravity=(0, 0, -G))
    _tank(b, width)
    body = b.add_body(position=(width / 2, period / 2, depth + bh / 2 + dx / 2))
    b.add_box(body, half_extents=(bw / 2, period / 2, bh / 2), density=relative_density * 1000.0)
    rigid = RigidWorld(b.finalize(), dt=1 / 200, substeps=4, enable_sleep=False)
    while rigid.state.time < 1.2:
        rigid.step()
        fluid.advance(rigid.dt, rigid)
    bottom = rigid.state.body_q[body, 2] - bh / 2
    if relative_density > 1:
        assert bottom < dx, bottom
    else:
        level = np.percentile(fluid.x[np.abs(fluid.x[:, 0] - width / 2) > bw / 2 + 0.05, 2], 99) + dx / 2
        draft = level - bottom
        assert bottom > depth / 2 and 0.25 * bh < draft < 0.75 * bh, (bottom, draft)
