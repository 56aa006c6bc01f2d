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


# ------------------------------------------------------------------------------ runaway (issue 11)
def _tall_column(**kw):
    # The root cause of the 20 000-particle dam break (bench_sph.dam_break(2, 0.01)) falling apart,
    # at half its width: a column 2 m = 200 spacings tall starting at rest with the 5 ms step.
    # DFSPH's stopping criterion was the *mean* compression over all particles (Bender & Koschier
    # 2017); here the compression sits in the bottom rows (1 % of the particles), so a mean of
    # 0.1 % left them compressed by 3-20 % (and the floor pushed with half the mirrored pressure,
    # so the bottom rows needed 1.5x the hydrostatic pressure). The next solve removes that
    # compression within one step, at a speed e dx / dt (e the relative compression); that speed
    # shortens the CFL step, which raises the speed again: the step collapsed towards 1e-6 s
    # while every value stayed finite. At spacing 0.02 the column is 100 rows tall and the mean
    # dilutes half as much, which is why that scene held.
    dx, w, height = 0.01, 0.5, 2.0
    fluid = SPHFluid(sample_block((0.0, 0.0), (w, height), dx), spacing=dx, domain=((0.0, 0.0), (4 * w, 2.2)), **kw)
    fluid.add_boundary(ia.colliders.Container(center=(2 * w, 1.1), half_extents=(2 * w, 1.1)), slip=True)
    return fluid, height


def test_mean_only_criterion_runs_away_and_raises_simulation_diverged():
    # Deliberately unstable: the mean-only criterion (local_density_tolerance=1, i.e. 100 %) and
    # 3 iterations per solve leave the bottom rows compressed; within 0.1 s (about a dozen steps)
    # a particle exceeds 10x the speed scale sqrt(2 g H_domain) or the step falls below 1e-3 of
    # the CFL step at that scale (measured: the latter at step 12, the fastest particles at
    # 53 m/s) and the step raises, naming the step, the fastest particles and the likely cause,
    # instead of crawling on at 1e-7 s steps. Measured with the defaults of 2026-11-26: Akinci's
    # boundary pressure, from zero pressure (velocities given: no hydrostatic start); with the
    # mirrored boundary pressure (with or without the hydrostatic start) the column held even with
    # these settings over 0.1 s (measured).
    fluid, _ = _tall_column(local_density_tolerance=1.0, max_iterations=3, velocities=np.zeros((10000, 2)),
                            boundary_pressure="akinci")
    with pytest.raises(SimulationDiverged, match=r"ran away: .* likely cause: time step") as info:
        while fluid.time < 0.1:
            fluid.step()
    assert info.value.indices.size == 10 and info.value.step == fluid.step_count
    assert "Fastest particles (ids)" in str(info.value)


def test_tall_column_holds_with_the_local_tolerance():
    # Default criterion (mean 0.1 % and every particle within 1 %; an unconverged solve halves
    # the next steps): the same column collapses smoothly. Bounds: after every step the solver's
    # summed density stays within 10 % of rho0 everywhere and within 3 % after 0.05 s (measured
    # 2026-11-27, default "mirror" boundary pressure and hydrostatic start: 1.8 % throughout;
    # Akinci's boundary pressure from zero pressure: 8 % in the start transient, 1.8 % late; the
    # default from zero pressure: 9.6 %, 3.8 % late; the mean-only run: 19-35 % before it raises); no
    # particle is faster than Ritter's dam-break front speed 2 sqrt(g H) (shallow-water theory,
    # the fastest motion of a collapsing column); no particle is lost.
    fluid, height = _tall_column()
    n0 = fluid.particle_count
    rho_max, rho_late, v_max = 0.0, 0.0, 0.0
    while fluid.time < 0.1:
        fluid.step()
        rho_max = max(rho_max, fluid.density.max())
        if fluid.time > 0.05:
            rho_late = max(rho_late, fluid.density.max())
        v_max = max(v_max, fluid.stats["max_speed"])
    assert rho_max < 1.10 * fluid.rest_density and rho_late < 1.03 * fluid.rest_density, (rho_max, rho_late)
    assert v_max < 2 * np.sqrt(G * height), v_max
    assert fluid.particle_count == n0
    assert fluid.stats.get("unconverged_solves", 0) <= 3


def test_collapsing_time_step_raises_simulation_diverged():
    # With the speed check switched off (runaway_speed huge), a particle at 1e5 m/s (finite)
    # makes the adaptive CFL step 0.4 dx / 1e5 = 8e-8 s, below 1e-3 of the CFL step at the
    # flow's speed scale (8 m/s here: 1e-6 s): the step raises instead of crawling on.
    fluid = SPHFluid(_block(), spacing=0.02, domain=((0.0, 0.0), (1.0, 1.0)), runaway_speed=1e9)
    fluid.step()
    fluid._F.v[5, 1] = 1e5
    with pytest.raises(SimulationDiverged, match="adaptive step fell to .* likely cause: time step") as info:
        fluid.step()
    assert fluid.particle_id[5] in info.value.indices[:1]


def _wcsph_box():
    fluid = SPHFluid(_block(), spacing=0.02, domain=((0.0, 0.0), (1.0, 1.0)), method="wcsph")
    fluid.add_boundary(ia.colliders.Container(center=(0.5, 0.5), half_extents=(0.5, 0.5)), slip=True)
    return fluid


def test_fluid_shot_out_of_the_domain_raises_simulation_diverged():
    # Deliberately unstable: WCSPH (Becker & Teschner 2007) with dt = 0.02 s forced on every step,
    # 160x its acoustic CFL limit cfl h / (c + v) = 1.2e-4 s (c = sqrt(2 g H) / sqrt(0.001) = 44
    # m/s). The compression of one step turns into a Tait pressure that throws the block apart:
    # measured, 20 of the 100 particles beyond the walls after step 1 (20 %, below the 25 % share),
    # 48 of the 80 left after step 2. Before, the sort dropped them silently and the run ended
    # with no particles and no error. No particle may leave a closed box through its walls, so
    # losing more than a quarter of the fluid in one step is a blow-up, named with the step, the
    # particles and the cause.
    fluid = _wcsph_box()
    with pytest.raises(SimulationDiverged, match=r"left the domain .* likely cause: stiffness/time step") as info:
        for _ in range(10):
            fluid.step(dt=0.02)
    e = info.value
    assert e.step == fluid.step_count - 1 and e.step >= 1
    lost = int(str(e).split(" blew up: ")[1].split(" of ")[0])
    assert e.indices.size == lost > 0.25 * 80
    assert np.all((e.indices >= 0) & (e.indices < 100)) and np.unique(e.indices).size == lost
    assert fluid.stats["escaped"] >= lost


def test_stable_wcsph_step_loses_no_particle_and_outflow_is_not_a_blow_up():
    # Control: the same box at its own (acoustic) adaptive step keeps every particle; and a fluid
    # that falls entirely into an outflow region at once is removed without an error (outflow is
    # not an escape through the domain bounds).
    fluid = _wcsph_box()
    for _ in range(20):
        fluid.step()
    assert fluid.particle_count == 100 and fluid.stats.get("escaped", 0) == 0
    out = SPHFluid(_block(), spacing=0.02, domain=((0.0, 0.0), (1.0, 1.0)))
    out.add_outflow((0.0, 0.0), (0.5, 0.5))
    out.step()
    assert out.particle_count == 0 and out.stats["removed"] == 100 and out.stats.get("escaped", 0) == 0


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
    # DFSPH with the default boundary pressure ("mirror") and solver settings, at the default
    # density tolerance 0.1 %, 15 x 20 particles: every step's constant-density solve ends below
    # the tolerance (mean compression); over 10 s the free surface does not drift (within half a
    # spacing of its 1 s value) and the summed density below the surface layers stays compressed
    # by less than twice the tolerance on average (see below); the floor carries the column's
    # weight M g within 5 % (time average over 1-10 s; measured 0.976).
    # Hydrostatics layer by layer: the pressure of each row of particles (one spacing thick,
    # away from the side walls), time-averaged with the step lengths over 1-10 s, within 5 % of
    # rho0 g (H - y), H the measured free surface, in every row deeper than one kernel support
    # below it (18 of 20 rows, the floor row included; the two surface rows have a truncated
    # kernel). Measured 2026-11-27 (defaults, momentum in the long creeping density solves): floor
    # row 1.012, rows 0.997-1.032 (the rows near the surface alternate by a few % in the time
    # average: 0.95-1.05 with other momentum settings), floor load 0.976. Akinci's boundary pressure: floor row 1.7x (next
    # test). Every solver setting is the default (max_iterations=100): the momentum of the
    # long constant-density solves meets the tolerance in 20.2 iterations per step, 99 at most (the plain
    # relaxed Jacobi crept from ~2e-3 towards it and missed it in 33 of 2757 steps, measured).
    dx, width, height = 0.02, 0.3, 0.4
    fluid = _column("dfsph", dx, width, height, viscosity=0.01, xsph=0.05)
    assert fluid.boundary_pressure == "mirror" and not fluid.warm_start_divergence
    assert fluid.max_iterations == 100 and fluid.density_tolerance == 1e-3
    weight = fluid.mass * fluid.particle_count * G
    rows = int(round(height / dx))
    ratio_sum, weight_sum = np.zeros(rows), 0.0
    loads, surfaces, means = [], [], []
    while fluid.time < 10.0:
        fluid.step()
        assert fluid.stats["density_error"] <= fluid.density_tolerance, (fluid.time, fluid.stats)
        assert fluid.stats["max_density_error"] <= fluid.local_density_tolerance, (fluid.time, fluid.stats)
        if fluid.time > 1.0:
            dt = fluid.last_dt
            loads.append(-fluid.body_force[0, 1] * dt)
            surfaces.append(np.percentile(fluid.x[:, 1], 99) + dx / 2)
            deep = fluid.x[:, 1] < surfaces[-1] - 2 * fluid.support
            means.append(np.maximum(fluid.density[deep] - fluid.rest_density, 0.0).mean() / fluid.rest_density)
            x, p = fluid.x, fluid.pressure
            inner = np.abs(x[:, 0] - width / 2) < width / 2 - 2 * dx
            row = np.clip((x[:, 1] / dx).astype(int), 0, rows - 1)
            for r in range(rows):
                sel = inner & (row == r)
                ratio_sum[r] += dt * p[sel].mean() / (fluid.rest_density * G * (surfaces[-1] - x[sel, 1].mean()))
            weight_sum += dt
    load = sum(loads) / (fluid.time - 1.0)
    assert abs(load - weight) < 0.05 * weight, (load, weight)
    assert abs(surfaces[-1] - surfaces[0]) < 0.5 * dx
    ratio = ratio_sum / weight_sum
    below = (np.arange(rows) + 0.5) * dx < np.mean(surfaces) - fluid.support
    assert below.sum() == rows - 2
    assert np.all(np.abs(ratio[below] - 1.0) < 0.05), ratio
    # the solver's error is the DFSPH mean over *all* particles (zero in the uncompressed surface
    # layers); below them the summed density is compressed 1.7x that on average (measured), so the
    # bound here is 2x the tolerance on average and 3x at any sample.
    assert np.mean(means) <= 2 * fluid.density_tolerance and max(means) <= 3 * fluid.density_tolerance, (
        np.mean(means), max(means))


def test_block_at_rest_starts_with_its_hydrostatic_pressure():
    # A DFSPH block at rest starts with p = rho0 g (H - y) (H half a spacing above the top
    # particle of each column of particles) as the warm start of its first constant-density
    # solve: the closed form on an L-shaped block (two column heights), and the 20-row column's
    # first 20 solves then need at most 5 iterations each (measured 1-3; starting from zero
    # pressure: up to 136, measured, the load building up over the first steps).
    from inertia.fluids.sph.fluid import hydrostatic_pressure
    dx = 0.02
    x = np.vstack([sample_block((0.0, 0.0), (0.1, 0.3), dx), sample_block((0.1, 0.0), (0.2, 0.1), dx)])
    top = np.where(x[:, 0] < 0.1, 0.3, 0.1)
    assert np.allclose(hydrostatic_pressure(x, (0.0, -G), dx, 1000.0), 1000.0 * G * (top - x[:, 1]), rtol=0, atol=1e-9)
    fluid = _column("dfsph", dx, 0.3, 0.4)
    for _ in range(20):
        fluid.step()
        assert fluid.stats["density_iterations"] <= 5, fluid.stats
    assert fluid.stats.get("unconverged_solves", 0) == 0


def test_dfsph_hydrostatic_rows_with_akinci_boundary_pressure():
    # boundary_pressure="akinci" (Akinci et al. 2012: the wall pushes with k_i alone, half the
    # mirrored push; the default until 2026-11-27), warm-started divergence solve: the same column
    # over 1-3 s. Rows 2-16 within 5 % of rho0 g (H - y) (measured 0.96-1.03); the floor row
    # carries the wall's missing half: above 1.4x (measured 1.7x), which is what the default
    # boundary_pressure="mirror" removes (previous test).
    dx, width, height = 0.02, 0.3, 0.4
    fluid = _column("dfsph", dx, width, height, viscosity=0.01, xsph=0.05, max_iterations=400,
                    warm_start_divergence=True, boundary_pressure="akinci")
    rows = int(round(height / dx))
    ratio_sum, weight_sum = np.zeros(rows), 0.0
    while fluid.time < 3.0:
        fluid.step()
        if fluid.time > 1.0:
            x, p, dt = fluid.x, fluid.pressure, fluid.last_dt
            surface = np.percentile(x[:, 1], 99) + dx / 2
            inner = np.abs(x[:, 0] - width / 2) < width / 2 - 2 * dx
            row = np.clip((x[:, 1] / dx).astype(int), 0, rows - 1)
            for r in range(rows):
                sel = inner & (row == r)
                ratio_sum[r] += dt * p[sel].mean() / (fluid.rest_density * G * (surface - x[sel, 1].mean()))
            weight_sum += dt
    ratio = ratio_sum / weight_sum
    assert np.all(np.abs(ratio[2:17] - 1.0) < 0.05), ratio
    assert ratio[0] > 1.4, ratio


def test_extrapolated_wall_pressure_of_a_hydrostatic_field():
    # Adami, Hu & Adams (2012): p_b = Shepard average of p_f + rho_f (g . n_b)(n_b . (x_b - x_f)).
    # For the linear field p_f = rho0 g (H - y_f) every term equals rho g (H - y_b) up to the
    # summed density's deviation from rho0 (rho_f in the body-force term): the floor's boundary
    # particles that see fluid carry rho0 g (H - y_b) within 0.5 % of rho0 g H, the side walls'
    # (normal horizontal: no body-force share) the Shepard average of the pressures beside them,
    # between those of the rows they see. Normals from the colliders: (0, 1) on the floor, (1, 0)
    # and (-1, 0) on the side walls.
    dx, width, height = 0.02, 0.3, 0.4
    fluid = _column("dfsph", dx, width, height, boundary_pressure="extrapolated")
    fluid.step()
    F, B = fluid._F, fluid._B
    n = fluid.particle_count
    F.k_dens[:n] = fluid.rest_density * G * (height - F.x[:n, 1]) / F.rho[:n] ** 2
    fluid._boundary_lists()
    kb = np.zeros(B.x.shape[0])
    fluid._K.boundary_extrapolated_pressure(F, B, fluid.grid, B.x.shape[0], fluid._bt_start, fluid._bt[0],
                                            fluid._bt[1], fluid._b_normal, F.k_dens, fluid.rest_density,
                                            fluid._g3, kb)
    seen = np.diff(fluid._bt_start) > 0
    pb = kb * fluid.rest_density ** 2
    floor = seen & (B.body == 0) & (np.abs(B.x[:, 0] - width / 2) < width / 2 - fluid.support)
    side = seen & (B.body < 0) & (B.x[:, 1] > 2 * dx)
    assert floor.sum() >= 10 and side.sum() >= 20
    assert np.allclose(fluid._b_normal[floor], [0.0, 1.0])
    assert np.allclose(np.abs(fluid._b_normal[side]), [1.0, 0.0])
    exact = fluid.rest_density * G * (height - B.x[floor, 1])
    assert np.abs(pb[floor] - exact).max() < 5e-3 * fluid.rest_density * G * height, np.abs(pb[floor] - exact).max()
    beside = fluid.rest_density * G * (height - B.x[side, 1])
    assert np.abs(pb[side] - beside).max() < fluid.rest_density * G * fluid.support, np.abs(pb[side] - beside).max()


def test_dfsph_hydrostatic_rows_with_extrapolated_boundary_pressure():
    # boundary_pressure="extrapolated": the wall particles carry the Shepard average of the fluid's
    # pressure plus the wall-normal body-force share (Adami, Hu & Adams 2012), no divergence warm
    # start: the same column over 1-4 s. Hydrostatics rho0 g (H - y): the floor row within 5 %
    # (measured 1.04; Akinci's single term: 1.7x, previous test), every row deeper than one support
    # below the surface within 7 % (measured 0.97-1.05: rows near the surface alternate by a few %
    # in the time average, layering that the mirrored solver increments leave), the floor carries
    # the weight within 5 % (measured 0.979), every solve meets the tolerance.
    dx, width, height = 0.02, 0.3, 0.4
    fluid = _column("dfsph", dx, width, height, viscosity=0.01, xsph=0.05, max_iterations=400,
                    boundary_pressure="extrapolated")
    weight = fluid.mass * fluid.particle_count * G
    rows = int(round(height / dx))
    ratio_sum, weight_sum, load = np.zeros(rows), 0.0, 0.0
    surfaces = []
    while fluid.time < 4.0:
        fluid.step()
        assert fluid.stats["density_error"] <= fluid.density_tolerance, (fluid.time, fluid.stats)
        if fluid.time > 1.0:
            x, p, dt = fluid.x, fluid.pressure, fluid.last_dt
            surface = np.percentile(x[:, 1], 99) + dx / 2
            surfaces.append(surface)
            inner = np.abs(x[:, 0] - width / 2) < width / 2 - 2 * dx
            row = np.clip((x[:, 1] / dx).astype(int), 0, rows - 1)
            for r in range(rows):
                sel = inner & (row == r)
                ratio_sum[r] += dt * p[sel].mean() / (fluid.rest_density * G * (surface - x[sel, 1].mean()))
            weight_sum += dt
            load -= fluid.body_force[0, 1] * dt
    ratio = ratio_sum / weight_sum
    below = (np.arange(rows) + 0.5) * dx < np.mean(surfaces) - fluid.support
    assert below.sum() == rows - 2
    assert abs(ratio[0] - 1.0) < 0.05, ratio
    assert np.all(np.abs(ratio[below] - 1.0) < 0.07), ratio
    assert abs(load / weight_sum - weight) < 0.05 * weight, (load / weight_sum, weight)


# ------------------------------------------------------------------------------ dam break
# Martin, J. C. & Moyce, W. J. (1952), "An experimental study of the collapse of liquid columns on
# a rigid horizontal plane", Phil. Trans. R. Soc. A 244, fig. 3: surge front Z = z / a against
# T = t sqrt(2 g / a) for a column of width a and height 2a (n^2 = 2), points read off the
# figure for a = 2.25 in and a = 1.125 in.
MARTIN_MOYCE = np.array([
    (0.832, 1.217), (0.849, 1.245), (1.212, 1.443), (1.219, 1.474), (1.602, 1.884), (1.997, 2.292),
    (2.283, 2.689), (2.547, 2.995), (2.950, 3.728)])


# Residual column height H = eta / (2a) (eta the height of the water at the wall the column
# stands against) against T = t sqrt(2 g / a), n^2 = 2: Martin & Moyce (1952), as replotted by
# Koshizuka, S. & Oka, Y. (1996), "Moving-particle semi-implicit method for fragmentation of
# incompressible fluid", Nucl. Sci. Eng. 123, 421-434 (their comparison of the water column's height).
MARTIN_MOYCE_HEIGHT = np.array([
    (1.07, 0.90), (1.56, 0.78), (2.05, 0.67), (2.56, 0.57), (3.12, 0.43), (3.83, 0.33), (4.83, 0.22)])


def test_dam_break_surge_front_and_residual_height_against_martin_and_moyce():
    # Coarse 2D DFSPH dam break: a = 0.2 m, 20 x 40 particles, free-slip floor and side walls of
    # a tank 5a wide (open top, 4a domain height), run to T = 5.
    # Front: the experiment's gate takes a finite time to lift, so the measured front starts late
    # and every simulation without a gate runs ahead of it (e.g. 10-20 % for SPH and VOF codes in
    # the literature); the front *speed* is not affected. Checks for T <= 3: (1) the front speed
    # dZ/dT (least squares over the points with 1.2 <= T <= 3) within 10 % of the experiment's;
    # (2) at every point the front is ahead of the experiment by at most 25 % and never behind
    # by more than 5 %.
    # Residual height: the top of the water within two spacings of the left wall, in units of
    # the initial height 2a, at every published point T <= 4.83 within 0.05 of the experiment,
    # i.e. two particle spacings (the free surface is resolved to about one spacing, the digitised
    # points to about 0.01; the gate matters little here because the height only starts falling
    # once the rarefaction reaches the wall, T ~ 1). Measured: within 0.02 at every point.
    a, dx = 0.2, 0.01
    length, height = 5 * a, 4 * a
    fluid = SPHFluid(sample_block((0.0, 0.0), (a, 2 * a), dx), spacing=dx, domain=((0.0, 0.0), (length, height)))
    for point, normal in (((0.0, 0.0), (0.0, 1.0)), ((0.0, 0.0), (1.0, 0.0)), ((length, 0.0), (-1.0, 0.0))):
        fluid.add_boundary(ia.colliders.Plane(point=point, normal=normal), slip=True)
    scale = np.sqrt(2 * G / a)
    history = []
    while fluid.time * scale < 5.0:
        fluid.step()
        x = fluid.x
        at_wall = x[:, 0] < 2 * dx
        history.append((fluid.time * scale, (x[:, 0].max() + dx / 2) / a, (x[at_wall, 1].max() + dx / 2) / (2 * a)))
    assert fluid.particle_count == 800  # none escaped
    history = np.array(history)
    T, Z = MARTIN_MOYCE[:, 0], MARTIN_MOYCE[:, 1]
    sim = np.interp(T, history[:, 0], history[:, 1])
    late = T >= 1.2
    slope_exp = np.polyfit(T[late], Z[late], 1)[0]
    slope_sim = np.polyfit(T[late], sim[late], 1)[0]
    assert abs(slope_sim - slope_exp) < 0.10 * slope_exp, (slope_sim, slope_exp)
    ratio = sim / Z
    assert np.all(ratio < 1.25) and np.all(ratio > 0.95), ratio
    T_h, H = MARTIN_MOYCE_HEIGHT[:, 0], MARTIN_MOYCE_HEIGHT[:, 1]
    sim_h = np.interp(T_h, history[:, 0], history[:, 2])
    assert np.all(np.abs(sim_h - H) < 0.05), sim_h - H


def test_wcsph_dam_break_residual_height_against_martin_and_moyce():
    # The coarse dam break of the test above (a = 0.2 m, 20 x 40 particles, inviscid, slip walls)
    # in WCSPH with its default boundary pressure (Akinci et al. 2012's single term): the top of
    # the water within two spacings of the wall the column stood against, in units of 2a, within
    # 0.05 of Martin & Moyce's residual height at every published point T <= 4.83 (two particle
    # spacings, as above), and no particle leaves the tank. Measured: within 0.047 (T = 4.83).
    # With the mirrored wall pressure (k_b = k_i, the WCSPH default before) the Tait pressure's
    # noise, answered twice by the wall, threw spray up that wall: 0.17 at T = 3.12 and 0.38 at
    # T = 3.83 above the experiment, and particles left the tank over its top.
    a, dx = 0.2, 0.01
    length, height = 5 * a, 4 * a
    fluid = SPHFluid(sample_block((0.0, 0.0), (a, 2 * a), dx), spacing=dx, domain=((0.0, 0.0), (length, height)),
                     method="wcsph")
    assert fluid.boundary_pressure == "akinci"
    for point, normal in (((0.0, 0.0), (0.0, 1.0)), ((0.0, 0.0), (1.0, 0.0)), ((length, 0.0), (-1.0, 0.0))):
        fluid.add_boundary(ia.colliders.Plane(point=point, normal=normal), slip=True)
    scale = np.sqrt(2 * G / a)
    T_h, H = MARTIN_MOYCE_HEIGHT[:, 0], MARTIN_MOYCE_HEIGHT[:, 1]
    history = []
    while fluid.time * scale < T_h[-1] + 0.05:
        fluid.step()
        x = fluid.x
        at_wall = x[:, 0] < 2 * dx
        history.append((fluid.time * scale, (x[at_wall, 1].max() + dx / 2) / (2 * a)))
    assert fluid.particle_count == 800  # none escaped
    history = np.array(history)
    sim_h = np.interp(T_h, history[:, 0], history[:, 1])
    assert np.all(np.abs(sim_h - H) < 0.05), sim_h - H


def test_default_boundary_pressure_per_method():
    x = sample_block((0.0, 0.0), (0.1, 0.1), 0.02)
    assert SPHFluid(x, spacing=0.02, domain=((0.0, 0.0), (1.0, 1.0))).boundary_pressure == "mirror"
    assert SPHFluid(x, spacing=0.02, domain=((0.0, 0.0), (1.0, 1.0)), method="wcsph").boundary_pressure == "akinci"
    fluid = SPHFluid(x, spacing=0.02, domain=((0.0, 0.0), (1.0, 1.0)), method="wcsph", boundary_pressure="mirror")
    assert fluid.boundary_pressure == "mirror"


# ------------------------------------------------------------------------------ Poiseuille
def test_poiseuille_flow_profile_periodic_channel_implicit_viscosity():
    # Plane Poiseuille flow: channel 0 < y < L, periodic in x, body force f along x, no-slip
    # walls; steady u(y) = f / (2 nu) y (L - y), u_max = f L^2 / (8 nu). 30 particles across,
    # L = 1 m, nu = 0.5 m^2/s, u_max = 0.1 m/s (Re = 0.2); 1.2 s = 6 decay times of the slowest
    # transient mode (exp(-pi^2 nu t / L^2) = 3e-3). Implicit viscosity (Weiler et al. 2018) at
    # dt = 2 ms, about 10x the explicit limit 0.125 h^2 / nu. The row-averaged profile within 5 %
    # of u_max of the closed form (measured 3.4 %; the explicit solver at its own limit: 6.6-7.6 %,
    # the rows next to the walls slip), the flux within 3 %.
    n_across, length, nu, u_max = 30, 1.0, 0.5, 0.1
    dx = length / n_across
    force = 8 * nu * u_max / length ** 2
    period = 10 * dx
    fluid = SPHFluid(sample_block((0.0, 0.0), (period, length), dx), spacing=dx,
                     domain=((0.0, 0.0), (period, length)), periodic=(True, False), gravity=(force, 0.0),
                     viscosity=nu, max_speed=2 * u_max, implicit_viscosity=True, dt_max=2e-3)
    fluid.add_boundary(ia.colliders.Plane(point=(0.0, 0.0), normal=(0.0, 1.0)))
    fluid.add_boundary(ia.colliders.Plane(point=(0.0, length), normal=(0.0, -1.0)))
    explicit_limit = 0.125 * fluid.h ** 2 / (nu * fluid._visc_scale)
    while fluid.time < 1.2:
        assert fluid.step() > 8 * explicit_limit
    y, u = fluid.x[:, 1], fluid.v[:, 0]
    rows = np.clip((y / dx).astype(int), 0, n_across - 1)
    u_row = np.bincount(rows, u, n_across) / np.bincount(rows, None, n_across)
    y_row = (np.arange(n_across) + 0.5) * dx
    exact = force / (2 * nu) * y_row * (length - y_row)
    assert np.abs(u_row - exact).max() < 0.05 * u_max, np.abs(u_row - exact).max() / u_max
    assert abs(u_row.mean() / exact.mean() - 1.0) < 0.03
    assert fluid.stats["viscosity_iterations"] < 200


# ------------------------------------------------------------------------------ floating box
def _drop_box(relative_density, duration):
    # 2D tank 1.5 x 0.5 m of water, dx = 0.025; a free rigid box 0.5 x 0.3 m (mass, inertia,
    # position, rotation integrated here with symplectic Euler from the fluid's body_force and
    # body_torque) released with its bottom at the surface.
    dx, width, depth, bw, bh = 0.025, 1.5, 0.5, 0.5, 0.3
    x = sample_block((0.0, 0.0), (width, depth), dx)
    cx, cy = width / 2, depth + bh / 2 + dx / 2
    fluid = SPHFluid(x, spacing=dx, domain=((0.0, 0.0), (width, depth + 0.6)), viscosity=5e-3, xsph=0.05,
                     max_iterations=200)
    fluid.add_boundary(ia.colliders.Container(center=(width / 2, (depth + 0.6) / 2),
                                              half_extents=(width / 2, (depth + 0.6) / 2)))
    body = fluid.add_body(ia.colliders.Box(center=(cx, cy), half_extents=(bw / 2, bh / 2)))
    mass = relative_density * fluid.rest_density * bw * bh
    inertia = mass * (bw ** 2 + bh ** 2) / 12
    pos, vel, angle, omega = np.array([cx, cy]), np.zeros(2), 0.0, 0.0
    drafts, bottoms = [], []
    while fluid.time < duration:
        c, s = np.cos(angle), np.sin(angle)
        fluid.set_body_state(body, pos, [[c, -s], [s, c]], vel, (0.0, 0.0, omega))
        dt = fluid.step()
        vel = vel + dt * (fluid.body_force[body, :2] / mass + np.array([0.0, -G]))
        pos = pos + dt * vel
        omega += dt * fluid.body_torque[body, 2] / inertia
        angle += dt * omega
        far = np.abs(fluid.x[:, 0] - cx) > bw / 2 + 0.2
        level = np.percentile(fluid.x[far, 1], 99) + dx / 2
        drafts.append((fluid.time, level - (pos[1] - bh / 2)))
        bottoms.append(pos[1] - bh / 2)
    return np.array(drafts), np.array(bottoms), bh, dx


@pytest.mark.parametrize("relative_density", [0.5, 0.8])
def test_floating_box_draft_from_archimedes(relative_density):
    # Archimedes: a floating box of density rho_b = s rho0 and height b sinks to the draft
    # d = s b (the displaced water weighs what the box weighs). The box heaves about that draft,
    # damped by viscosity and waves; the mean draft over the last 1.5 s of 3 s (about one and a
    # half heave periods) within 5 % of s b (measured 2026-11-27, mirrored boundary pressure: 1.009
    # for s = 0.5, 1.049 for 0.8; Akinci's: 0.99, 1.04-1.07). The box floats 0.1-0.5 spacings low
    # here (on a vertical guide: 0.07 and 0.4 by the surface particles), while the 3-D slab
    # boxes of test_coupling float 0.2 spacings high: the gap under the box equals the floor's
    # (0.49-0.51 spacings, measured), so the offset is not in the sampling.
    drafts, _, bh, _ = _drop_box(relative_density, 3.0)
    late = drafts[:, 0] > 1.5
    mean = drafts[late, 1].mean()
    assert abs(mean - relative_density * bh) < 0.05 * relative_density * bh, (mean, relative_density * bh)


def test_dense_box_sinks():
    # A box twice as dense as the water sinks to the tank floor (its bottom within two spacings
    # of the floor after 1.5 s; it starts 0.5 m above it).
    _, bottoms, _, dx = _drop_box(2.0, 1.5)
    assert bottoms[-1] < 2 * dx, bottoms[-1]


# ------------------------------------------------------------------------------ determinism
_DETERMINISM_SCENE = textwrap.dedent("""
    import hashlib, numpy as np, inertia as ia
    from inertia.fluids.sph import SPHFluid, sample_block
    dx = 0.01
    x = sample_block((0.0, 0.0), (0.48, 0.48), dx)          # 2304 particles
    fluid = SPHFluid(x, spacing=dx, domain=((0.0, 0.0), (1.0, 0.8)), viscosity=1e-3, xsph=0.02,
                     surface_tension=0.1)
    fluid.add_boundary(ia.colliders.Container(center=(0.5, 0.4), half_extents=(0.5, 0.4)))
    body = fluid.add_body(ia.colliders.Box(center=(0.7, 0.1), half_extents=(0.05, 0.05)))
    for _ in range(25):
        fluid.step()
    h = hashlib.sha256()
    for arr in (fluid.x, fluid.v, fluid.particle_id, fluid.body_force):
        h.update(np.ascontiguousarray(arr).tobytes())
    print(h.hexdigest()[:16], fluid.step_count)
""")
# A particle without pressure takes only the wall-normal part of the wall's hydrostatic share
# (kernels._hydrostatic_share; the previous hash 326e922a03119923 had the full offset): the scene's
# free-surface particles beside its walls move differently; measured at NUMBA_NUM_THREADS=1 and 2
# (serial twins and parallel kernels)
GOLDEN_HASH = "77ac014ed1779bc5"


def _hash_at(threads, serial_below=None):
    env = dict(os.environ, NUMBA_NUM_THREADS=str(threads))
    if serial_below is not None:
        env["INERTIA_SERIAL_BELOW"] = str(serial_below)
    out = subprocess.run([sys.executable, "-c", _DETERMINISM_SCENE], env=env, capture_output=True, text=True,
                         timeout=900, check=True)
    return out.stdout.split()[0]


def test_same_state_hash_at_one_and_two_threads():
    # Parallel passes only gather (each particle writes its own row); the sort is serial and
    # stable; reductions use fixed chunks; body wrenches are summed serially: the state is
    # bit-identical at any thread count, and equal to the stored golden hash. The scene is small
    # enough for the serial twins (kernels.kernel_set); the 2-thread run forces the parallel
    # kernels (INERTIA_SERIAL_BELOW=0), the ones large scenes run.
    one, two = _hash_at(1), _hash_at(2, serial_below=0)
    assert one == two
    assert one == GOLDEN_HASH


# ------------------------------------------------------------------------------ emitters, outflow
def test_emitter_rate_and_outflow_removal():
    # An emitter of width w and speed u releases one layer of round(w / dx) particles each time
    # the previous layer has travelled one spacing: after time t, 1 + floor(u t / dx) layers.
    # Particles entering the outflow box are removed at the next step; particle ids keep
    # counting. No gravity, no walls: the jet travels freely.
    dx, u, width = 0.02, 1.0, 0.2
    seed = sample_block((0.0, 0.0), (0.04, 0.04), dx)        # 4 particles far from the jet
    fluid = SPHFluid(seed, spacing=dx, domain=((0.0, 0.0), (2.0, 1.0)), gravity=(0.0, 0.0), capacity=2000,
                     dt_max=0.004)
    fluid.add_emitter(center=(0.1, 0.5), velocity=(u, 0.0), width=width)
    fluid.add_outflow((1.0, 0.0), (2.0, 1.0))
    per_layer = round(width / dx)
    while fluid.time < 0.5:
        fluid.step()
    layers = 1 + int(np.floor(u * fluid.time / dx + 1e-9))
    emitted = int(fluid.particle_id.max()) + 1 - seed.shape[0]
    assert emitted == layers * per_layer
    assert fluid.particle_count == seed.shape[0] + emitted          # nothing reached x = 1 yet
    while fluid.time < 1.5:
        fluid.step()
    assert fluid.x[:, 0].max() < 1.0 + u * fluid.last_dt + 1e-9    # removed on entering x >= 1
    assert fluid.stats["removed"] > 0
    assert fluid.particle_count + fluid.stats["removed"] == int(fluid.particle_id.max()) + 1


# ------------------------------------------------------------------------------ surface tension
def test_surface_tension_rounds_a_square_drop():
    # Akinci et al. 2013: cohesion and curvature forces minimise the surface; a square drop
    # without gravity becomes round. The square's corner particles sit at 0.134 m from the
    # centre, the circle of equal area has radius 0.113 m; after 0.5 s with surface tension the
    # farthest particle is within 0.125 m, while without it (control) the corners stay out.
    dx = 0.01
    x = sample_block((0.4, 0.4), (0.6, 0.6), dx)

    def farthest(tension):
        fluid = SPHFluid(x, spacing=dx, domain=((0.0, 0.0), (1.0, 1.0)), gravity=(0.0, 0.0),
                         surface_tension=tension, viscosity=1e-3)
        while fluid.time < 0.5:
            fluid.step()
        return np.linalg.norm(fluid.x - fluid.x.mean(axis=0), axis=1).max()

    assert farthest(TENSION) < 0.125
    assert farthest(0.0) > 0.13


TENSION = 0.005  # measured: the farthest particle reaches 0.116 m by 0.5 s (0.02: 0.124; 0.5: the drop bursts)


# ------------------------------------------------------------------------------ thick bodies
def test_fluid_in_a_thick_body_core_is_pushed_out_through_the_nearest_face():
    # A body is sampled with a band one kernel support thick; its core holds no boundary
    # particles, and fluid that got through the band stayed there (measured: a density-2 box of
    # 16 x 9.6 spacings sinking onto the floor of a 3-D slab tank, RigidWorld coupling, had 218
    # fluid particles in its core after 2 s; with the push-out at most 1 at any step after it).
    # Here the fluid lattice fills a held box 0.5 x 0.5 m (20 x 20 spacings): after one step every
    # particle that was deeper than a support inside sits half a spacing outside the face nearest
    # to it (the box's signed distance, closed form: max_e |x_e - c_e| - 0.25 = dx / 2), with the
    # body's velocity (at rest: 0); none is left in the core.
    dx = 0.025
    centre, half = np.array([0.75, 0.5]), 0.25
    x = sample_block((0.0, 0.0), (1.5, 1.0), dx)
    fluid = SPHFluid(x, spacing=dx, domain=((0.0, 0.0), (1.5, 1.2)))
    body = fluid.add_body(ia.colliders.Box(center=centre, half_extents=(half, half)))
    depth0 = (np.abs(x - centre) - half).max(axis=1)
    core0 = int((depth0 < -fluid.support).sum())
    assert core0 == 16 * 16
    fluid.step()
    assert fluid.stats["pushed_out"] == core0
    depth = (np.abs(fluid.x - centre) - half).max(axis=1)
    assert not np.any(depth < -fluid.support)
    on_face = np.abs(depth - dx / 2) < 1e-12
    assert on_face.sum() >= core0
    assert np.all(fluid.v[on_face] == 0.0) and body == 0


# ------------------------------------------------------------------------------ walls create no momentum
@pytest.mark.parametrize("method,mode", [("dfsph", "mirror"), ("wcsph", "mirror"), ("dfsph", "akinci"),
                                         ("wcsph", "akinci"), ("dfsph", "extrapolated")])
def test_droplet_falling_along_a_slip_wall_is_not_braked(method, mode):
    # Free fall: a 5 x 5 droplet released at rest beside a vertical slip wall (no floor) has no
    # pressure and nothing along the wall acts on it, so its mean velocity is -g t (momentum: the
    # fluid-fluid forces are equal and opposite, a slip wall pushes only along its normal). At
    # t = 0.1 s within 1 % of g t (measured: DFSPH mirror 0.5 % braked, as the wall lattice
    # under the sliding particles gives those that carry pressure the full hydrostatic share;
    # WCSPH mirror and DFSPH akinci exact, extrapolated 0.05 %). Before a particle without
    # pressure took only the wall-normal part of the share (kernels._hydrostatic_share) the mirror
    # mode reached -0.965 m/s (1.6 % braked; WCSPH -0.969).
    dx = 0.01
    fluid = SPHFluid(sample_block((0.0, 0.5), (0.05, 0.55), dx), spacing=dx, domain=((0.0, 0.0), (0.3, 0.6)),
                     method=method, boundary_pressure=mode, max_speed=1.0)
    fluid.add_boundary(ia.colliders.Plane(point=(0.0, 0.0), normal=(1.0, 0.0)), slip=True)
    while fluid.time < 0.1 - 1e-12:
        fluid.step(at_most=0.1 - fluid.time)
    assert fluid.particle_count == 25
    assert abs(fluid.v[:, 1].mean() / (-G * fluid.time) - 1.0) < 1e-2, fluid.v[:, 1].mean()


@pytest.mark.parametrize("mode", ["mirror", "akinci", "extrapolated"])
def test_wcsph_channel_driven_by_a_body_force_gains_no_momentum_from_its_walls(mode):
    # A periodic channel (slip walls at y = 0 and 0.2 m, 20 rows, 12 columns) driven by a body
    # force F = 1 m/s^2 along it, no gravity into the walls: the walls push only along their
    # normal, so the fluid's mean velocity never exceeds F t (Newton's second law; the pressure
    # the walls answer with can only brake the flow by the lattice's friction). Checked every step
    # to t = 0.3 s: mean u <= F t (1 + 1e-9). Before the wall's hydrostatic share took the minimum
    # image across the periodic axis (kernels._hydrostatic_share), the mirror mode's walls saw the
    # body force's share g . (x_b - x_i) of a neighbour a period away and the mean velocity
    # exceeded F t by t = 0.18 s.
    dx, width, period, force, t_end = 0.01, 0.2, 0.12, 1.0, 0.3
    fluid = SPHFluid(sample_block((0.0, 0.0), (period, width), dx), spacing=dx, domain=((0.0, 0.0), (period, width)),
                     periodic=(True, False), gravity=(force, 0.0), method="wcsph", boundary_pressure=mode,
                     max_speed=force * t_end)
    fluid.add_boundary(ia.colliders.Plane(point=(0.0, 0.0), normal=(0.0, 1.0)), slip=True)
    fluid.add_boundary(ia.colliders.Plane(point=(0.0, width), normal=(0.0, -1.0)), slip=True)
    while fluid.time < t_end - 1e-12:
        fluid.step(at_most=t_end - fluid.time)
        assert fluid.v[:, 0].mean() <= force * fluid.time * (1 + 1e-9), (fluid.time, fluid.v[:, 0].mean())
    assert fluid.particle_count == 240


def _run_driven_channel(check_start=False, **options):
    """A periodic channel (0.12 m long, 0.2 m wide, spacing 0.01) between two slip walls, driven along
    its axis by a body force F = 1 m/s^2 with nothing pulling across it, run to t = 1 s from rest; at
    every step the mean velocity stays within the free acceleration F t and |v_y| under 2 % of F t."""
    dx, width, period, force, t_end = 0.01, 0.2, 0.12, 1.0, 1.0
    fluid = SPHFluid(sample_block((0.0, 0.0), (period, width), dx), spacing=dx, domain=((0.0, 0.0), (period, width)),
                     periodic=(True, False), gravity=(force, 0.0), max_speed=force * t_end, **options)
    if check_start:
        assert np.all(fluid._F.k_dens == 0.0)   # no hydrostatic start along the periodic axis
    fluid.add_boundary(ia.colliders.Plane(point=(0.0, 0.0), normal=(0.0, 1.0)), slip=True)
    fluid.add_boundary(ia.colliders.Plane(point=(0.0, width), normal=(0.0, -1.0)), slip=True)
    while fluid.time < t_end - 1e-12:
        fluid.step(at_most=t_end - fluid.time)
        ft = force * fluid.time
        assert fluid.v[:, 0].mean() <= ft * (1 + 1e-9), (fluid.time, fluid.v[:, 0].mean())
        assert np.abs(fluid.v[:, 1]).max() < 0.02 * ft, (fluid.time, np.abs(fluid.v[:, 1]).max())
    assert fluid.particle_count == 240


def test_dfsph_channel_driven_by_a_body_force_stays_parallel_to_its_walls():
    # The same channel in DFSPH with Akinci's boundary pressure, started at rest, to t = 1 s: the
    # flow accelerates freely along the periodic axis, mean u <= F t (1 + 1e-9) and |v_y| < 2 % of
    # F t at every step (Newton's second law). Measured: |v_y| <= 0.44 % of F t. Before the
    # hydrostatic start (the warm start of the first density solve) left out the periodic axes,
    # the block started with a pressure ramp along the channel that jumped at the seam: |v_y|
    # reached 6.2 % of F t and the mean velocity 1.0035 F t. (The mirror mode is a known issue:
    # docs/fluids-sph.md.)
    _run_driven_channel(boundary_pressure="akinci", check_start=True)


def test_wcsph_channel_driven_by_a_body_force_stays_parallel_to_its_walls():
    # The channel above with WCSPH's default boundary pressure (Akinci's single term) to t = 1 s:
    # the walls push only along their normal and nothing pushes across the channel, so the flow
    # accelerates freely along it: mean u <= F t (1 + 1e-9) and |v_y| < 2 % of F t at every step
    # (Newton's second law for the free acceleration of the whole channel). The lattice start is
    # uncompressed and stays so (measured: |v_y| = 0, mean u = F t). With the mirrored wall pressure
    # (the WCSPH default before) the run diverged at t = 0.56 s.
    _run_driven_channel(method="wcsph")
