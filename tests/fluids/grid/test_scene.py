"""The [fluids.NAME] scene table (inertia.fluids.grid.scene)."""

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
