"""The [fluids.NAME] scene table (inertia.fluids.grid.scene)."""

import numpy as np
import pytest

import inertia as ia
from inertia.fluids.grid import GridFluid, LiquidFluid
from inertia.fluids.grid.scene import build

SMOKE = {"shape": [16, 24], "cell_size": 1 / 16, "buoyancy": [0.1, 1.0], "obstacles": ["ball"],
         "boundaries": {"y+": {"type": "outflow"}, "y-": {"type": "slip"}},
         "sources": [{"lower": [0.4, 0.05], "upper": [0.6, 0.2], "density_rate": 5.0}]}


def test_smoke_and_liquid_tables_build_and_step():
    ball = ia.colliders.Sphere(center=(0.5, 0.9), radius=0.15)
    f = build(SMOKE, colliders={"ball": ball}, name="plume")
    assert isinstance(f, GridFluid) and f.obstacles == [ball] and len(f.sources) == 1
    f.advance(0.05)
    assert f.scalar("density").max() > 0
    liq = build({"kind": "liquid", "shape": [16, 16], "cell_size": 1 / 16, "method": "flip",
                 "blocks": [{"lower": [0, 0], "upper": [0.5, 0.5]}]}, name="tank")
    assert isinstance(liq, LiquidFluid) and liq.particle_count == 16 * 16 // 4 * 4
    liq.advance(1 / 60)


@pytest.mark.parametrize("patch,key", [
    ({"shape": [2, 16]}, "fluids.plume.shape"),
    ({"cell_size": 0.0}, "fluids.plume.cell_size"),
    ({"viscosity": -1.0}, "fluids.plume.viscosity"),
    ({"advection": "upwind"}, "fluids.plume.advection"),
    ({"cfl": 9.0}, "fluids.plume.cfl"),
    ({"colour": "red"}, "fluids.plume.colour"),
    ({"obstacles": ["cube"]}, "fluids.plume.obstacles[0]"),
    ({"boundaries": {"x-": {"type": "inflow"}}}, "fluids.plume.boundaries.x-"),
    ({"sources": [{"lower": [5.0, 5.0], "upper": [6.0, 6.0]}]}, "fluids.plume.sources[0]"),
])
def test_bad_input_names_the_key(patch, key):
    table = dict(SMOKE, obstacles=[]) | patch
    with pytest.raises(ValueError) as e:
        build(table, colliders={"ball": ia.colliders.Sphere(center=(0.5, 0.9), radius=0.15)}, name="plume")
    assert str(e.value).startswith(key), str(e.value)


def test_diffusion_pressure_sides_and_inflow_profiles_reach_the_fluid():
    f = build({"shape": [16, 8], "cell_size": 1 / 8, "viscosity": 0.01, "fluid_density": 1000.0,
               "diffusivity": {"temperature": 1e-3},
               "boundaries": {"x-": {"type": "pressure", "pressure": 2.0}, "x+": {"type": "pressure", "pressure": 0.0},
                              "y-": {"type": "wall", "temperature": 1.5}}}, name="duct")
    assert f.diffusivity == {"temperature": 1e-3} and f.fluid_density == 1000.0
    assert [p for _, _, p in f._pressure_sides] == [2.0, 0.0]
    assert f.sides[2].temperature == 1.5
    f.step(0.05)
    assert f.u.mean() > 0.0 and f.scalar("temperature")[:, 0].mean() > 0.0
    g = build({"shape": [16, 8], "cell_size": 1 / 8,
               "boundaries": {"x-": {"type": "inflow", "velocity": [1.0, 0.0], "profile": "parabolic"},
                              "x+": {"type": "outflow"}}}, name="duct")
    y = (np.arange(8) + 0.5) / 8
    np.testing.assert_allclose(g.u[0], 6 * y * (1 - y))
    ball = ia.colliders.Sphere(center=(0.5, 0.5), radius=0.2)
    h = build({"shape": [16, 16], "cell_size": 1 / 16, "obstacles": ["ball"], "obstacle_temperature": [2.0],
               "diffusivity": {"temperature": 1e-2}}, colliders={"ball": ball}, name="stove")
    h.step(0.1)
    assert h.scalar("temperature")[8, 8] == 2.0 and h.scalar("temperature")[8, 3] > 0.0


@pytest.mark.parametrize("patch,key", [
    ({"boundaries": {"x-": {"type": "pressure"}}}, "fluids.plume.boundaries.x-.pressure"),
    ({"boundaries": {"x-": {"type": "outflow", "pressure": 1.0}}}, "fluids.plume.boundaries.x-.pressure"),
    ({"boundaries": {"x-": {"type": "wall", "profile": "parabolic"}}}, "fluids.plume.boundaries.x-.profile"),
    ({"boundaries": {"x-": {"type": "inflow", "velocity": [1.0, 0.0], "profile": "cosine"}}},
     "fluids.plume.boundaries.x-.profile"),
    ({"boundaries": {"x-": {"type": "inflow", "velocity": [1.0, 0.0]}}}, "fluids.plume.boundaries"),   # no outlet
    ({"diffusivity": {"smoke": 1.0}}, "fluids.plume.diffusivity"),
    ({"fluid_density": 0.0}, "fluids.plume.fluid_density"),
    ({"obstacle_temperature": "hot"}, "fluids.plume.obstacle_temperature"),
    ({"obstacle_temperature": 1.0, "obstacles": ["ball"]}, "fluids.plume.obstacle_temperature"),   # no diffusivity
])
def test_bad_diffusion_and_boundary_keys_name_the_key(patch, key):
    table = dict(SMOKE, obstacles=[], boundaries={}) | patch
    with pytest.raises(ValueError) as e:
        build(table, colliders={"ball": ia.colliders.Sphere(center=(0.5, 0.9), radius=0.15)}, name="plume")
    assert str(e.value).startswith(key), str(e.value)


TANK = {"kind": "liquid", "shape": [32, 16], "cell_size": 1 / 16, "viscosity": 0.01,
        "obstacles": ["rock", "post"], "obstacle_slip": [False, True],
        "boundaries": {"y-": {"type": "no-slip"}, "x+": {"type": "slip"}},
        "blocks": [{"lower": [0.0, 0.0], "upper": [0.6, 0.7]}]}
ROCKS = {"rock": ia.colliders.Sphere(center=(1.0, 0.2), radius=0.15),
         "post": ia.colliders.Box(center=(1.5, 0.2), half_extents=(0.05, 0.2))}


def test_viscous_liquid_around_obstacles_builds_and_runs():
    # viscosity, per-obstacle slip flags, no-slip floor: the table reaches the LiquidFluid and a
    # few frames run (the dam break reaches the no-slip rock and the slip post)
    f = build(TANK, colliders=ROCKS, name="tank")
    assert isinstance(f, LiquidFluid) and f.viscosity == 0.01
    assert f._slip == [False, True] and len(f.obstacles) == 2
    assert f._wall_no_slip[1, 0] and not f._wall_no_slip[0, 1]
    for _ in range(3):
        f.advance(1 / 30)
    assert f.last_viscous_iterations > 0
    for o in ROCKS.values():   # no particle inside an obstacle
        assert float(np.min(o.signed_distance(f.positions()))) > 0.0
    g = build(dict(TANK, obstacle_slip=True), colliders=ROCKS, name="tank")
    assert g._slip == [True, True]
    s = build(dict(SMOKE, viscosity=0.01, obstacle_slip=[True]),
              colliders={"ball": ia.colliders.Sphere(center=(0.5, 0.9), radius=0.15)}, name="plume")
    assert s._slip == [True]


@pytest.mark.parametrize("patch,key,word", [
    ({"obstacle_slip": "yes"}, "fluids.tank.obstacle_slip", "true, false"),
    ({"obstacle_slip": [True]}, "fluids.tank.obstacle_slip", "2 bools"),
    ({"boundaries": {"x-": {"type": "inflow", "velocity": [1.0, 0.0]}}}, "fluids.tank.boundaries.x-",
     "no-slip"),
    ({"boundaries": {"x-": {"type": "wall", "velocity": [1.0, 0.0]}}}, "fluids.tank.boundaries.x-.velocity",
     "do not move"),
    ({"obstacles": ["cube"]}, "fluids.tank.obstacles[0]", "rock"),
    ({"viscosity": -0.5}, "fluids.tank.viscosity", ""),
])
def test_bad_liquid_input_names_the_key(patch, key, word):
    with pytest.raises(ValueError) as e:
        build(TANK | patch, colliders=ROCKS, name="tank")
    assert str(e.value).startswith(key), str(e.value)
    assert word in str(e.value), str(e.value)
