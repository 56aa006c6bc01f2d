"""The shape table's type codes and the per-type parameter layout (one table for every system).

Every collision shape is one row of the Model's shape table (see ``inertia.model``):

============== ===== ===================================================================
type            code  ``shape_params`` columns (metres)
============== ===== ===================================================================
SPHERE          0     radius
BOX             1     half extents hx, hy, hz
CAPSULE         2     radius, half length of the core segment along local z
CYLINDER        3     radius, half height along local z
CONVEX_HULL     4     unused (vertices in ``geom_vertices`` by ``shape_vert_start/count``)
TRIANGLE_MESH   5     triangle count T (static; triangle list + BVH, see geometry/trimesh_collide.py)
PLANE           6     unused: the plane is the local z = 0 plane, normal +z, solid z <= 0
HEIGHTFIELD     7     nx, ny, dx, dy (static; grid points in geom_vertices, trimesh_collide.py)
SDF             8     rest-frame offset ox, oy, oz of the row frame (static/kinematic; grid: sdf_collide.py)
============== ===== ===================================================================

Shape poses are given in the owning body's frame (centre of mass, principal axes); ``shape_body``
is -1 for static world geometry.
"""

from __future__ import annotations

SPHERE = 0
BOX = 1
CAPSULE = 2
CYLINDER = 3
CONVEX_HULL = 4
TRIANGLE_MESH = 5
PLANE = 6
HEIGHTFIELD = 7

SHAPE_NAMES = {
    "sphere": SPHERE, "box": BOX, "capsule": CAPSULE, "cylinder": CYLINDER,
    "convex_hull": CONVEX_HULL, "triangle_mesh": TRIANGLE_MESH, "plane": PLANE,
    "heightfield": HEIGHTFIELD,
}

#: body motion types (``body_type`` column of the Model)
DYNAMIC = 0
KINEMATIC = 1
STATIC = 2
BODY_TYPE_NAMES = {"dynamic": DYNAMIC, "kinematic": KINEMATIC, "static": STATIC}

__all__ = ["SPHERE", "BOX", "CAPSULE", "CYLINDER", "CONVEX_HULL", "TRIANGLE_MESH", "PLANE",
           "HEIGHTFIELD", "SHAPE_NAMES", "DYNAMIC", "KINEMATIC", "STATIC", "BODY_TYPE_NAMES"]

#: a signed-distance collider (``inertia.colliders.SDF``, or a triangle mesh the rigid side cannot use) as
#: a shape-table row, static or on a kinematic body. Baked to a grid, its packed GRID data sits in the
#: Model's ``sdf_grid_f``/``sdf_grid_i`` from ``shape_sdf_start``, ``shape_params[:3]`` is the rest-frame
#: position of the row's frame and ``geom_vertices`` the 8 corners of the field's box (row frame); dynamic
#: bodies' convex shapes collide with it by surface samples (``inertia.geometry.sdf_collide``). Unbaked
#: rows have no grid and are seen by particles only (through the collider's own data).
SDF = 8
__all__ += ["SDF"]
