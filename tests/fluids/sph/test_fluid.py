"""SPHFluid: bad input, momentum conservation, hydrostatic column (WCSPH and DFSPH), determinism.

The physics references are written next to each check; tolerances are tied to the method
(the density tolerance, the WCSPH sound speed) and to the particle spacing.
"""

import hashlib
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import inertia as ia
from inertia.errors import SimulationDiverged
from inertia.fluids.sph import SPHFluid, sample_block

G = 9.81


# ------------------------------------------------------------------------------ bad input
def _block():
    return sample_block((0.0, 0.0), (0.2, 0.2), 0.02)


@pytest.mark.parametrize("kwargs,match", [
    (dict(rest_density=0.0), "rest_density"),
    (dict(rest_density=-5.0), "rest_density"),
    (dict(smoothing_length=0.1), "smoothing_length"),
    (dict(smoothing_length=0.01), "smoothing_length"),
    (dict(method="sph"), "method must be one of"),
    (dict(kernel="gauss"), "kernel must be one of"),
    (dict(spacing=0.0), "spacing"),
    (dict(domain=((0, 0), (0.01, 1.0))), "domain"),
    (dict(domain=((0.1, 0), (1, 1))), "positions must lie inside the domain"),
    (dict(periodic=(True, False), smoothing_length=0.04, domain=((0, 0), (0.2, 1))), "periodic axis 0"),
    (dict(dt=0.05), "dt = 0.05 s is above the stability limit"),
    (dict(method="wcsph", dt=1e-3), "acoustic"),
    (dict(density_tolerance=0.5), "density_tolerance"),
    (dict(max_iterations=1), "max_iterations"),
    (dict(viscosity=-1.0), "viscosity"),
    (dict(cfl=2.0), "cfl"),
])
def test_bad_input_names_the_argument(kwargs, match):
    args = dict(spacing=0.02, domain=((0.0, 0.0), (1.0, 1.0)))
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        SPHFluid(_block(), **args)


def test_emitter_outside_domain_and_wrong_collider_are_named():
    fluid = SPHFluid(_block(), spacing=0.02, domain=((0.0, 0.0), (1.0, 1.0)))
    with pytest.raises(ValueError, match="center must lie inside the domain"):
        fluid.add_emitter(center=(2.0, 0.5), velocity=(1.0, 0.0), width=0.1)
    with pytest.raises(ValueError, match="collider must be a 2-D collider"):
        fluid.add_boundary(ia.colliders.Plane(point=(0, 0, 0), normal=(0, 0, 1)))
    with pytest.raises(ValueError, match="collider must be a Box or Sphere"):
        fluid.add_body(ia.colliders.Plane(point=(0, 0), normal=(0, 1)))


def test_blow_up_raises_simulation_diverged():
    fluid = SPHFluid(_block(), spacing=0.02, domain=((0.0, 0.0), (1.0, 1.0)))
    fluid.step()
    fluid._F.v[3, 0] = np.nan
    with pytest.raises(SimulationDiverged, match="non-finite velocities") as info:
        fluid.step()
    assert info.value.indices.size >= 1


# ------------------------------------------------------------------------------ momentum
@pytest.mark.parametrize("method", ["dfsph", "wcsph"])
def test_momentum_conserved_without_gravity_in_a_periodic_box(method):
    # Every pair force (pressure (k_i + k_j) g_ij, viscosity, XSPH, cohesion and curvature) is
    # equal and opposite and all particles share one mass, so the total momentum
    # sum_i m v_i is conserved to round-off when nothing outside acts (no gravity, no walls:
    # a fully periodic box). A random velocity field compresses the fluid so that every term
    # is active.
    rng = np.random.default_rng(7)
    dx = 0.02
    x = sample_block((0.0, 0.0), (0.3, 0.3), dx) + rng.normal(0.0, 0.1 * dx, size=(225, 2))
    v = rng.normal(0.0, 0.3, size=x.shape)
    fluid = SPHFluid(np.mod(x, 0.3), velocities=v, spacing=dx, domain=((0.0, 0.0), (0.3, 0.3)),
                     periodic=(True, True), gravity=(0.0, 0.0), viscosity=1e-3, xsph=0.05,
                     surface_tension=0.5, method=method, max_speed=1.0)
    p0 = fluid.mass * fluid.v.sum(axis=0)
    for _ in range(40):
        fluid.step()
    p1 = fluid.mass * fluid.v.sum(axis=0)
    scale = fluid.mass * np.abs(fluid.v).sum()
    assert np.all(np.abs(p1 - p0) < 1e-12 * scale), (p0, p1)
    assert fluid.stats["max_speed"] > 0.1  # the flow did not simply stop


# ------------------------------------------------------------------------------ hydrostatics
def _column(method, dx, width, height, **kw):
    x = sample_block((0.0, 0.0), (width, height), dx)
    fluid = SPHFluid(x, spacing=dx, domain=((0.0, 0.0), (width, height + 4 * dx)), method=method, **kw)
    # side walls static; the floor a body held at rest, so that its load is measured
    fluid.add_boundary(ia.colliders.Plane(point=(0.0, 0.0), normal=(1.0, 0.0)))
    fluid.add_boundary(ia.colliders.Plane(point=(width, 0.0), normal=(-1.0, 0.0)))
    fluid.add_body(ia.colliders.Box(center=(width / 2, -0.1), half_extents=(width / 2, 0.1)))
    return fluid


def test_wcsph_hydrostatic_pressure_profile():
    # Hydrostatics: p(y) = rho0 g (H - y). WCSPH with density_tolerance 1 % (sound speed
    # c = sqrt(2 g H / 0.01)); the column starts from the unloaded lattice, so it rings
    # acoustically; viscosity damps it. Layer-averaged pressure (away from the free surface
    # and the walls) within 5 % of rho0 g (H - y), H the measured free surface; the mean
    # compression stays within the 1 % tolerance.
    dx, width, height = 0.02, 0.3, 0.4
    fluid = _column("wcsph", dx, width, height, density_tolerance=1e-2, viscosity=0.01)
    layers = (0.05, 0.15, 0.25)
    sums, samples = np.zeros(len(layers)), 0
    while fluid.time < 1.5:
        fluid.step()
        assert fluid.stats["density_error"] < 1e-2
        if fluid.time > 0.5 and fluid.step_count % 10 == 0:
            # time average over 0.5-1.5 s (many acoustic periods 4 H / c = 0.05 s)
            x, p = fluid.x, fluid.pressure
            surface = np.percentile(x[:, 1], 99) + dx / 2
            for k, y in enumerate(layers):
                layer = (np.abs(x[:, 1] - y) < dx) & (np.abs(x[:, 0] - width / 2) < width / 2 - 2 * dx)
                sums[k] += p[layer].mean() / (fluid.rest_density * G * (surface - y))
            samples += 1
    ratio = sums / samples
    assert np.all(np.abs(ratio - 1.0) < 0.05), ratio


def test_dfsph_hydrostatic_column_holds_without_drift():
    # DFSPH at the default density tolerance 0.1 %: every step's constant-density solve ends
    # below the tolerance (mean compression); over 10 s the free surface does not drift (within
    # half a spacing of its 1 s value) and the summed density below the surface layers stays
    # compressed by less than twice the tolerance on average (see below); the floor carries the column's weight,
    # i.e. the integral of the bottom pressure rho0 g H over the floor equals M g, within 5 %
    # (time average over 1-10 s). (Starting from zero pressure, the first steps need up to
    # ~300 iterations, hence max_iterations=400.)
    dx, width, height = 0.02, 0.3, 0.4
    fluid = _column("dfsph", dx, width, height, viscosity=0.01, xsph=0.05, max_iterations=400)
    weight = fluid.mass * fluid.particle_count * G
    loads, surfaces, means = [], [], []
    while fluid.time < 10.0:
        fluid.step()
        assert fluid.stats["density_error"] <= fluid.density_tolerance, (fluid.time, fluid.stats)
        if fluid.time > 1.0:
            loads.append(-fluid.body_force[0, 1] * fluid.last_dt)
            surfaces.append(np.percentile(fluid.x[:, 1], 99))
            deep = fluid.x[:, 1] < surfaces[-1] - 2 * fluid.support
            means.append(np.maximum(fluid.density[deep] - fluid.rest_density, 0.0).mean() / fluid.rest_density)
    load = sum(loads) / (fluid.time - 1.0)
    assert abs(load - weight) < 0.05 * weight, (load, weight)
    assert abs(surfaces[-1] - surfaces[0]) < 0.5 * dx
    # the solver's error is the DFSPH mean over *all* particles (zero in the uncompressed surface
    # layers); below them the summed density is compressed 1.7x that on average (measured), so the
    # bound here is 2x the tolerance on average and 3x at any sample.
    assert np.mean(means) <= 2 * fluid.density_tolerance and max(means) <= 3 * fluid.density_tolerance, (
        np.mean(means), max(means))


# ------------------------------------------------------------------------------ dam break
# Martin, J. C. & Moyce, W. J. (1952), "An experimental study of the collapse of liquid columns on
# a rigid horizontal plane", Phil. Trans. R. Soc. A 244, fig. 3: surge front Z = z / a against
# T = t sqrt(2 g / a) for a column of width a and height 2a (n^2 = 2), points read off the
# figure for a = 2.25 in and a = 1.125 in.
MARTIN_MOYCE = np.array([
    (0.832, 1.217), (0.849, 1.245), (1.212, 1.443), (1.219, 1.474), (1.602, 1.884), (1.997, 2.292),
    (2.283, 2.689), (2.547, 2.995), (2.950, 3.728)])


def test_dam_break_surge_front_against_martin_and_moyce():
    # Coarse 2D DFSPH dam break: a = 0.2 m, 20 x 40 particles, free-slip tank 5a x 3a.
    # The experiment's gate takes a finite time to lift, so the measured front starts late and
    # every simulation without a gate runs ahead of it (e.g. 10-20 % for SPH and VOF codes in the
    # literature); the front *speed* is not affected. Checks: (1) the front speed dZ/dT (least
    # squares over the points with 1.2 <= T <= 3) within 10 % of the experiment's; (2) at every
    # point the front is ahead of the experiment by at most 25 % and never behind by more than 5 %.
    a, dx = 0.2, 0.01
    length, height = 5 * a, 3 * a
    fluid = SPHFluid(sample_block((0.0, 0.0), (a, 2 * a), dx), spacing=dx, domain=((0.0, 0.0), (length, height)))
    fluid.add_boundary(ia.colliders.Container(center=(length / 2, height / 2), half_extents=(length / 2, height / 2)),
                       slip=True)
    scale = np.sqrt(2 * G / a)
    history = []
    while fluid.time * scale < 3.0:
        fluid.step()
        history.append((fluid.time * scale, (fluid.x[:, 0].max() + dx / 2) / a))
    assert fluid.particle_count == 800  # none escaped through the walls
    history = np.array(history)
    T, Z = MARTIN_MOYCE[:, 0], MARTIN_MOYCE[:, 1]
    sim = np.interp(T, history[:, 0], history[:, 1])
    late = T >= 1.2
    slope_exp = np.polyfit(T[late], Z[late], 1)[0]
    slope_sim = np.polyfit(T[late], sim[late], 1)[0]
    assert abs(slope_sim - slope_exp) < 0.10 * slope_exp, (slope_sim, slope_exp)
    ratio = sim / Z
    assert np.all(ratio < 1.25) and np.all(ratio > 0.95), ratio
