"""Mass properties of rigid shapes: mass, centre of mass and inertia tensor, and the principal body frame.

Every shape function returns a ``MassProperties`` (mass, centre of mass, inertia tensor about the centre of
mass) in the shape's own frame.  ``transform_mass_properties`` moves it to a body frame by a pose,
``compound_mass_properties`` adds several shapes, and ``principal_frame`` diagonalises the sum so a body's
frame can sit at its centre of mass on its principal axes (the convention of the shape table).

Closed forms (uniform density rho, frame at the centroid, symmetry axis z; I_perp about x and y):
- box, half extents (a, b, c): m = 8 rho a b c, I_xx = m (b^2 + c^2) / 3 (cyclic).
- solid sphere r: m = 4/3 pi r^3 rho, I = 2/5 m r^2; thick shell r_i..r: I = 2/5 m (r^5 - r_i^5)/(r^3 - r_i^3);
  thin shell of surface density sigma: m = 4 pi r^2 sigma, I = 2/3 m r^2.
- cylinder r, half height h: m = 2 pi r^2 h rho, I_zz = m r^2 / 2, I_perp = m (r^2/4 + h^2/3).
- capsule r, half length h of the segment: cylinder m_c plus a sphere m_s split into two hemispheres whose
  centroids sit 3r/8 beyond the segment ends: I_zz = m_c r^2/2 + 2/5 m_s r^2,
  I_perp = m_c (r^2/4 + h^2/3) + m_s (2/5 r^2 + h^2 + 3 h r / 4).
- cone, base radius r, height H, frame at the centroid H/4 above the base, apex on +z:
  m = pi r^2 H rho / 3, I_zz = 3/10 m r^2, I_perp = 3/20 m r^2 + 3/80 m H^2.
- ellipsoid, semi-axes (a, b, c): m = 4/3 pi a b c rho, I_xx = m (b^2 + c^2) / 5 (cyclic).
- hemisphere r (frame at the centre of the flat face, dome on +z): m = 2/3 pi r^3 rho, centroid 3r/8 on z,
  I_zz = 2/5 m r^2, I_perp = 83/320 m r^2 about the centroid (2/5 m r^2 about the face centre); a thick
  hemispherical shell r_i..r: centroid 3/8 (r^4 - r_i^4)/(r^3 - r_i^3), 2/5 m (r^5 - r_i^5)/(r^3 - r_i^3)
  about the face centre.
- torus, major radius R (centre to tube centre), minor radius a <= R, axis z: m = 2 pi^2 R a^2 rho,
  I_zz = m (R^2 + 3/4 a^2), I_perp = m (R^2/2 + 5/8 a^2).
- thin rod of length L, linear density lambda, along z: m = lambda L, I_perp = m L^2/12 about its centre,
  m L^2/3 about an end, I_zz = 0.
- hollow cylinder (tube), outer radius R, inner radius r_i, half height h: open (no end caps)
  m = 2 pi (R^2 - r_i^2) h rho, I_zz = m (R^2 + r_i^2)/2, I_perp = m ((R^2 + r_i^2)/4 + h^2/3); closed: the
  solid cylinder (R, h) minus the cavity (r_i, h - t) for end caps of thickness t.
- thin cylindrical shell, radius r, half height h, surface density sigma: the lateral surface
  m = 4 pi r h sigma, I_zz = m r^2, I_perp = m (r^2/2 + h^2/3); closed adds two discs m_d = pi r^2 sigma at
  z = +-h (I_zz = m_d r^2/2, I_perp = m_d (r^2/4 + h^2)).
These are the textbook table entries (Hibbeler, Engineering Mechanics: Dynamics, 14th ed., Appendix
"Mass moments of inertia of homogeneous solids"; the torus and the shells by the same slice integration).

Polyhedra (closed, outward-wound triangle meshes and convex hulls) are integrated exactly with the
divergence theorem: the solid is the signed sum of the tetrahedra (o, a, b, c) joining a reference point o
to each face, and each tetrahedron's second moment is the closed form
    integral x x^T dV = det[a b c] / 120 (a a^T + b b^T + c c^T + s s^T),  s = a + b + c,
(Tonon 2005, eq. 7-9, written as a covariance as in Blow and Binstock 2004).  This is exact like Mirtich's
(1996) projection formulas: the results agree to rounding.

References
- Mirtich, B. (1996). Fast and accurate computation of polyhedral mass properties. Journal of Graphics
  Tools 1(2), 31-50.
- Tonon, F. (2005). Explicit exact formulas for the 3-D tetrahedron inertia tensor in terms of its vertex
  coordinates. Journal of Mathematics and Statistics 1(1), 8-11.
- Blow, J. and Binstock, A. J. (2004). How to find the inertia tensor (or other mass properties) of a 3D
  solid body represented by a triangle mesh.

Limitations
- Uniform density per shape (compounds may mix densities).
- Meshes must be closed, consistently and outwardly wound 2-manifolds (each directed edge used once and
  its reverse once); open or inside-out meshes raise ValueError (they have no meaningful inertia for a
  dynamic body).  Self-intersecting meshes are not detected (their overlapping volume counts twice).
- Planes and heightfields have no finite mass; they may only belong to static bodies.
"""

from __future__ import annotations

import math
from typing import NamedTuple, Sequence

import numpy as np

from inertia import math as im
from inertia._validate import positive_scalar

__all__ = [
    "MassProperties", "PrincipalFrame", "box_mass_properties", "sphere_mass_properties",
    "thin_spherical_shell_mass_properties", "capsule_mass_properties", "cylinder_mass_properties",
    "cone_mass_properties", "ellipsoid_mass_properties", "hemisphere_mass_properties", "torus_mass_properties",
    "thin_rod_mass_properties", "hollow_cylinder_mass_properties", "cylindrical_shell_mass_properties",
    "mesh_mass_properties",
    "convex_hull_mass_properties", "shape_mass_properties", "parallel_axis", "transform_mass_properties",
    "compound_mass_properties", "principal_frame",
]

# shape type codes of the shape table (same values as inertia.geometry.shapes, owned by rigid-core)
_SPHERE, _BOX, _CAPSULE, _CYLINDER, _CONVEX_HULL, _TRIANGLE_MESH, _PLANE, _HEIGHTFIELD = range(8)


class MassProperties(NamedTuple):
    """Mass properties in some frame F (the shape's local frame unless transformed).

    mass     float, kg.
    com      (3,) float64, m: centre of mass in F.
    inertia  (3, 3) float64, kg m^2: inertia tensor about the centre of mass, axes of F.
    """

    mass: float
    com: np.ndarray
    inertia: np.ndarray

    def scaled_to_mass(self, mass: float) -> "MassProperties":
        """The same shape with its density chosen to give ``mass`` (inertia scales linearly)."""
        mass = positive_scalar(mass, "mass")
        return MassProperties(mass, self.com.copy(), self.inertia * (mass / self.mass))

    def inertia_about(self, point=(0.0, 0.0, 0.0)) -> np.ndarray:
        """Inertia tensor (3, 3) about ``point`` of F (default F's origin), axes of F (parallel axis)."""
        p = np.asarray(point, dtype=np.float64).reshape(-1)
        if p.shape != (3,) or not np.all(np.isfinite(p)):
            raise ValueError(f"point must be 3 finite numbers (m); got {np.asarray(point).tolist()}")
        return parallel_axis(self.inertia, self.mass, p - self.com)


class PrincipalFrame(NamedTuple):
    """A body frame at the centre of mass on the principal axes, described in the input frame F.

    mass          float, kg.
    com           (3,) float64, m: origin of the body frame in F.
    inertia_diag  (3,) float64, kg m^2: principal moments, ascending.
    rotation      (4,) float64: unit quaternion (w, x, y, z) from body to F: x_F = com + R(rotation) x_body.
    """

    mass: float
    com: np.ndarray
    inertia_diag: np.ndarray
    rotation: np.ndarray

    @property
    def pose(self) -> np.ndarray:
        """The body frame as a pose (7,) (px, py, pz, qw, qx, qy, qz) in F."""
        return np.concatenate([self.com, self.rotation])


# ----------------------------------------------------------------------------------------- validation
def _positive_vector(value, name: str) -> np.ndarray:
    arr = np.asarray(value, dtype=np.float64).reshape(-1)
    if arr.shape != (3,) or not np.all(np.isfinite(arr)) or np.any(arr <= 0.0):
        raise ValueError(f"{name} must be 3 finite numbers > 0; got {np.asarray(value).tolist()}")
    return arr


def _diag(mass: float, ixx: float, iyy: float, izz: float) -> MassProperties:
    return MassProperties(mass, np.zeros(3), np.diag([ixx, iyy, izz]).astype(np.float64))


# ------------------------------------------------------------------------------------- closed forms
def box_mass_properties(half_extents, density: float) -> MassProperties:
    """Solid box with half extents (a, b, c) (m) and density (kg/m^3), centred at the origin."""
    a, b, c = _positive_vector(half_extents, "half_extents")
    rho = positive_scalar(density, "density")
    m = 8.0 * rho * a * b * c
    return _diag(m, m * (b * b + c * c) / 3.0, m * (a * a + c * c) / 3.0, m * (a * a + b * b) / 3.0)


def sphere_mass_properties(radius: float, density: float, *, inner_radius: float = 0.0) -> MassProperties:
    """Solid sphere, or a thick spherical shell when ``0 < inner_radius < radius`` (m)."""
    r = positive_scalar(radius, "radius")
    rho = positive_scalar(density, "density")
    ri = float(inner_radius)
    if not math.isfinite(ri) or ri < 0.0 or ri >= r:
        raise ValueError(f"inner_radius must satisfy 0 <= inner_radius < radius = {r}; got {inner_radius!r}")
    m = 4.0 / 3.0 * math.pi * rho * (r ** 3 - ri ** 3)
    # integral of (2/3) r'^2 dm over shells: 2/5 m (r^5 - ri^5) / (r^3 - ri^3)
    i = 0.4 * m * (r ** 5 - ri ** 5) / (r ** 3 - ri ** 3)
    return _diag(m, i, i, i)


def thin_spherical_shell_mass_properties(radius: float, surface_density: float) -> MassProperties:
    """Infinitely thin spherical shell of surface density (kg/m^2): I = 2/3 m r^2."""
    r = positive_scalar(radius, "radius")
    sigma = positive_scalar(surface_density, "surface_density")
    m = 4.0 * math.pi * r * r * sigma
    i = 2.0 / 3.0 * m * r * r
    return _diag(m, i, i, i)


def cylinder_mass_properties(radius: float, half_height: float, density: float) -> MassProperties:
    """Solid cylinder along local z, centred at the origin."""
    r = positive_scalar(radius, "radius")
    h = positive_scalar(half_height, "half_height")
    rho = positive_scalar(density, "density")
    m = 2.0 * math.pi * r * r * h * rho
    perp = m * (r * r / 4.0 + h * h / 3.0)
    return _diag(m, perp, perp, 0.5 * m * r * r)


def capsule_mass_properties(radius: float, half_length: float, density: float) -> MassProperties:
    """Capsule: the points within ``radius`` of the segment from (0, 0, -half_length) to (0, 0, half_length).

    ``half_length = 0`` is a sphere."""
    r = positive_scalar(radius, "radius")
    h = float(half_length)
    if not math.isfinite(h) or h < 0.0:
        raise ValueError(f"half_length must be a finite number >= 0; got {half_length!r}")
    rho = positive_scalar(density, "density")
    m_cyl = 2.0 * math.pi * r * r * h * rho
    m_sph = 4.0 / 3.0 * math.pi * r ** 3 * rho
    izz = 0.5 * m_cyl * r * r + 0.4 * m_sph * r * r
    perp = m_cyl * (r * r / 4.0 + h * h / 3.0) + m_sph * (0.4 * r * r + h * h + 0.75 * h * r)
    return _diag(m_cyl + m_sph, perp, perp, izz)


def cone_mass_properties(radius: float, height: float, density: float) -> MassProperties:
    """Solid right circular cone along local z, frame at its centroid: base disc at z = -height/4, apex at
    z = 3 height / 4."""
    r = positive_scalar(radius, "radius")
    hh = positive_scalar(height, "height")
    rho = positive_scalar(density, "density")
    m = math.pi * r * r * hh * rho / 3.0
    perp = 3.0 / 20.0 * m * r * r + 3.0 / 80.0 * m * hh * hh
    return _diag(m, perp, perp, 0.3 * m * r * r)


def ellipsoid_mass_properties(semi_axes, density: float) -> MassProperties:
    """Solid ellipsoid with semi-axes (a, b, c) along local x, y, z, centred at the origin."""
    a, b, c = _positive_vector(semi_axes, "semi_axes")
    rho = positive_scalar(density, "density")
    m = 4.0 / 3.0 * math.pi * a * b * c * rho
    return _diag(m, m * (b * b + c * c) / 5.0, m * (a * a + c * c) / 5.0, m * (a * a + b * b) / 5.0)


def _radius_pair(outer, inner, outer_name: str, inner_name: str):
    ro = positive_scalar(outer, outer_name)
    if isinstance(inner, bool) or not isinstance(inner, (int, float, np.integer, np.floating)):
        raise TypeError(f"{inner_name} must be a number (m); got {type(inner).__name__}")
    ri = float(inner)
    if not math.isfinite(ri) or ri < 0.0 or ri >= ro:
        raise ValueError(f"{inner_name} must satisfy 0 <= {inner_name} < {outer_name} = {ro}; got {inner!r}")
    return ro, ri


def hemisphere_mass_properties(radius: float, density: float, *, inner_radius: float = 0.0) -> MassProperties:
    """Solid hemisphere of ``radius`` (m), or a thick hemispherical shell (a bowl) when
    ``0 < inner_radius < radius``; density in kg/m^3.

    Frame F: origin at the centre of the flat face (the sphere's centre), the dome on +z. The centre of mass
    is (0, 0, 3r/8) for the solid (3/8 (r^4 - r_i^4) / (r^3 - r_i^3) for the shell); the inertia is about
    it: I_zz = 2/5 m r^2, I_xx = I_yy = 83/320 m r^2 for the solid (``inertia_about()`` gives 2/5 m r^2 about
    the face centre)."""
    r, ri = _radius_pair(radius, inner_radius, "radius", "inner_radius")
    rho = positive_scalar(density, "density")
    m = 2.0 / 3.0 * math.pi * rho * (r ** 3 - ri ** 3)
    zc = 3.0 / 8.0 * (r ** 4 - ri ** 4) / (r ** 3 - ri ** 3)
    # about the sphere's centre each half holds half of the full (shell's) moment, on every axis
    i_o = 0.4 * m * (r ** 5 - ri ** 5) / (r ** 3 - ri ** 3)
    perp = i_o - m * zc * zc
    return MassProperties(m, np.array([0.0, 0.0, zc]), np.diag([perp, perp, i_o]).astype(np.float64))


def torus_mass_properties(major_radius: float, minor_radius: float, density: float) -> MassProperties:
    """Solid torus about local z, centred at the origin: the tube of radius ``minor_radius`` (m) swept
    round the circle of radius ``major_radius`` (m) in the xy plane; ``minor_radius <= major_radius`` (a
    larger tube would overlap itself). I_zz = m (R^2 + 3 a^2 / 4), I_xx = I_yy = m (R^2 / 2 + 5 a^2 / 8)."""
    big = positive_scalar(major_radius, "major_radius")
    a = positive_scalar(minor_radius, "minor_radius")
    if a > big:
        raise ValueError(f"minor_radius must be <= major_radius = {big} (a self-overlapping torus has no "
                         f"closed form here); got {minor_radius!r}")
    rho = positive_scalar(density, "density")
    m = 2.0 * math.pi ** 2 * big * a * a * rho
    perp = m * (0.5 * big * big + 0.625 * a * a)
    return _diag(m, perp, perp, m * (big * big + 0.75 * a * a))


def thin_rod_mass_properties(length: float, linear_density: float, *, origin: str = "centre") -> MassProperties:
    """Thin rod (a line mass) of ``length`` (m) and ``linear_density`` (kg/m) along local z.

    ``origin``: "centre" puts F's origin at the rod's midpoint (centre of mass 0); "end" at one end, the rod
    running to (0, 0, length) (centre of mass (0, 0, L/2)). The inertia is about the centre of mass:
    I_xx = I_yy = m L^2 / 12; about the end (``inertia_about()`` with origin "end") m L^2 / 3. The moment
    about the rod's own axis is 0, so a dynamic body needs another part (or a cylinder or capsule of the
    rod's radius) to have a positive definite inertia."""
    length_ = positive_scalar(length, "length")
    lam = positive_scalar(linear_density, "linear_density")
    if origin not in ("centre", "end"):
        raise ValueError(f"origin must be 'centre' or 'end'; got {origin!r}")
    m = lam * length_
    perp = m * length_ * length_ / 12.0
    com = np.array([0.0, 0.0, 0.0 if origin == "centre" else 0.5 * length_])
    return MassProperties(m, com, np.diag([perp, perp, 0.0]).astype(np.float64))


def hollow_cylinder_mass_properties(outer_radius: float, inner_radius: float, half_height: float,
                                    density: float, *, closed: bool = False,
                                    cap_thickness: float | None = None) -> MassProperties:
    """Thick-walled tube along local z, centred at the origin: the solid between ``inner_radius`` and
    ``outer_radius`` (m) over -half_height..half_height; density in kg/m^3.

    ``closed=False`` (default): an open tube, I_zz = m (R^2 + r_i^2) / 2, I_perp = m ((R^2 + r_i^2)/4 + h^2/3).
    ``closed=True``: a closed can, whose end caps have thickness ``cap_thickness`` (m; default the wall
    thickness R - r_i, and less than half_height): the solid cylinder minus its cavity."""
    ro, ri = _radius_pair(outer_radius, inner_radius, "outer_radius", "inner_radius")
    h = positive_scalar(half_height, "half_height")
    rho = positive_scalar(density, "density")
    if not isinstance(closed, (bool, np.bool_)):
        raise TypeError(f"closed must be True or False; got {closed!r}")
    if not closed:
        if cap_thickness is not None:
            raise ValueError("cap_thickness applies to a closed tube only: pass closed=True")
        cavity_h = h
    else:
        t = ro - ri if cap_thickness is None else positive_scalar(cap_thickness, "cap_thickness")
        if t >= h:
            raise ValueError(f"cap_thickness must be < half_height = {h} (the caps would meet); got {t!r}")
        cavity_h = h - t
    m_out = 2.0 * math.pi * ro * ro * h * rho
    m_in = 2.0 * math.pi * ri * ri * cavity_h * rho
    m = m_out - m_in
    izz = 0.5 * (m_out * ro * ro - m_in * ri * ri)
    perp = m_out * (ro * ro / 4.0 + h * h / 3.0) - m_in * (ri * ri / 4.0 + cavity_h * cavity_h / 3.0)
    return _diag(m, perp, perp, izz)


def cylindrical_shell_mass_properties(radius: float, half_height: float, surface_density: float, *,
                                      closed: bool = False) -> MassProperties:
    """Infinitely thin cylindrical shell along local z, centred at the origin: the lateral surface of radius
    ``radius`` over -half_height..half_height (m), surface density in kg/m^2; ``closed=True`` adds the two
    end discs of the same surface density. Open: I_zz = m r^2, I_perp = m (r^2/2 + h^2/3)."""
    r = positive_scalar(radius, "radius")
    h = positive_scalar(half_height, "half_height")
    sigma = positive_scalar(surface_density, "surface_density")
    if not isinstance(closed, (bool, np.bool_)):
        raise TypeError(f"closed must be True or False; got {closed!r}")
    m_side = 4.0 * math.pi * r * h * sigma
    izz = m_side * r * r
    perp = m_side * (0.5 * r * r + h * h / 3.0)
    m = m_side
    if closed:
        m_disc = math.pi * r * r * sigma
        m += 2.0 * m_disc
        izz += m_disc * r * r
        perp += 2.0 * m_disc * (0.25 * r * r + h * h)
    return _diag(m, perp, perp, izz)


# ------------------------------------------------------------------------------------------ polyhedra
def _check_closed_mesh(triangles: np.ndarray, vertex_count: int, name: str) -> None:
    """Each directed edge (i, j) must occur exactly once and its reverse (j, i) exactly once."""
    t = triangles
    if np.any((t[:, 0] == t[:, 1]) | (t[:, 1] == t[:, 2]) | (t[:, 0] == t[:, 2])):
        bad = np.flatnonzero((t[:, 0] == t[:, 1]) | (t[:, 1] == t[:, 2]) | (t[:, 0] == t[:, 2]))
        raise ValueError(f"{name} has degenerate triangles (a repeated vertex) at rows {bad[:10].tolist()}")
    edges = np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])
    key = edges[:, 0] * vertex_count + edges[:, 1]
    uniq, counts = np.unique(key, return_counts=True)
    if np.any(counts > 1):
        e = uniq[counts > 1][0]
        raise ValueError(f"{name} is not a consistently wound closed mesh: the directed edge "
                         f"({e // vertex_count}, {e % vertex_count}) occurs {counts[counts > 1][0]} times "
                         "(neighbouring faces must traverse a shared edge in opposite directions)")
    reverse = edges[:, 1] * vertex_count + edges[:, 0]
    missing = ~np.isin(reverse, uniq)
    if np.any(missing):
        i, j = edges[np.flatnonzero(missing)[0]]
        raise ValueError(f"{name} is not closed: edge ({i}, {j}) has no opposite half-edge ({j}, {i}); a "
                         f"dynamic body needs a closed, outward-wound mesh ({int(missing.sum())} open edges)")


def _polyhedron_integrals(vertices: np.ndarray, triangles: np.ndarray):
    """Volume, centroid and second moment integral (x - c)(x - c)^T dV of a closed outward mesh (exact)."""
    # integrate about the vertex mean to keep the rounding error relative to the shape's size
    ref = vertices.mean(axis=0)
    p = vertices - ref
    a, b, c = p[triangles[:, 0]], p[triangles[:, 1]], p[triangles[:, 2]]
    det = np.einsum("ij,ij->i", a, np.cross(b, c))  # 6 x signed volume of tetrahedron (ref, a, b, c)
    s = a + b + c
    volume = det.sum() / 6.0
    first = (det[:, None] * s).sum(axis=0) / 24.0  # integral x dV: volume x centroid (ref + s / 4)
    second = (np.einsum("t,ti,tj->ij", det, a, a) + np.einsum("t,ti,tj->ij", det, b, b)
              + np.einsum("t,ti,tj->ij", det, c, c) + np.einsum("t,ti,tj->ij", det, s, s)) / 120.0
    return volume, first, second, ref


def mesh_mass_properties(vertices, triangles, density: float, *, name: str = "mesh") -> MassProperties:
    """Solid bounded by a closed triangle mesh wound counter-clockwise seen from outside (outward normals).

    Raises ValueError for open, inconsistently wound or inside-out meshes and for zero volume."""
    rho = positive_scalar(density, "density")
    v = np.asarray(vertices, dtype=np.float64)
    if v.ndim != 2 or v.shape[1] != 3 or v.shape[0] < 4 or not np.all(np.isfinite(v)):
        raise ValueError(f"{name} vertices must be a finite (V, 3) array with V >= 4; got shape {v.shape}")
    t = np.asarray(triangles)
    if t.ndim != 2 or t.shape[1] != 3 or t.shape[0] < 4 or not np.issubdtype(t.dtype, np.integer):
        raise ValueError(f"{name} triangles must be an integer (T, 3) array with T >= 4; got shape {t.shape}")
    t = t.astype(np.int64)
    if t.min() < 0 or t.max() >= v.shape[0]:
        raise ValueError(f"{name} triangles must index vertices 0..{v.shape[0] - 1}; got range "
                         f"{t.min()}..{t.max()}")
    _check_closed_mesh(t, v.shape[0], name)
    volume, first, second, ref = _polyhedron_integrals(v, t)
    scale3 = float(np.ptp(v, axis=0).prod()) or 1.0
    if volume <= 1e-12 * scale3:
        if volume < 0.0:
            raise ValueError(f"{name} is inside out (signed volume {volume:.6g} < 0): its triangles are wound "
                             "clockwise seen from outside; reverse each triangle's vertex order")
        raise ValueError(f"{name} encloses no volume (signed volume {volume:.6g})")
    centroid = first / volume
    # covariance about the centroid, then inertia = tr(C) E - C
    cov = rho * (second - volume * np.outer(centroid, centroid))
    inertia = np.trace(cov) * np.eye(3) - cov
    inertia = 0.5 * (inertia + inertia.T)
    return MassProperties(rho * volume, centroid + ref, inertia)


def convex_hull_mass_properties(points, density: float) -> MassProperties:
    """Solid convex hull of a point cloud (N, 3); ValueError for fewer than 4 points or a flat cloud."""
    from inertia.geometry.convex import build_convex_hull

    rho = positive_scalar(density, "density")
    hull = build_convex_hull(points, name="points")
    return mesh_mass_properties(hull.vertices, hull.triangles, rho, name="convex hull")


def shape_mass_properties(shape_type: int, params, density: float, *, vertices=None,
                          triangles=None) -> MassProperties:
    """Mass properties of one shape-table row in its local frame (see the contract's shape table).

    SPHERE (radius), BOX (hx, hy, hz), CAPSULE (radius, half length along z), CYLINDER (radius, half height
    along z), CONVEX_HULL (``vertices``), TRIANGLE_MESH (``vertices``, ``triangles``).  PLANE and HEIGHTFIELD
    have no finite mass: ValueError (they belong on static bodies)."""
    p = np.asarray(params, dtype=np.float64).reshape(-1)
    st = int(shape_type)
    if st == _SPHERE:
        return sphere_mass_properties(p[0], density)
    if st == _BOX:
        return box_mass_properties(p[:3], density)
    if st == _CAPSULE:
        return capsule_mass_properties(p[0], p[1], density)
    if st == _CYLINDER:
        return cylinder_mass_properties(p[0], p[1], density)
    if st == _CONVEX_HULL:
        if vertices is None:
            raise ValueError("vertices are required for a CONVEX_HULL shape")
        return convex_hull_mass_properties(vertices, density)
    if st == _TRIANGLE_MESH:
        if vertices is None or triangles is None:
            raise ValueError("vertices and triangles are required for a TRIANGLE_MESH shape")
        return mesh_mass_properties(vertices, triangles, density)
    if st in (_PLANE, _HEIGHTFIELD):
        raise ValueError(f"shape_type {st} (PLANE=6 or HEIGHTFIELD=7) has no finite mass; attach it to a static "
                         "body (body -1)")
    raise ValueError(f"shape_type must be one of 0..7 (SPHERE, BOX, CAPSULE, CYLINDER, CONVEX_HULL, "
                     f"TRIANGLE_MESH, PLANE, HEIGHTFIELD); got {shape_type!r}")


# ---------------------------------------------------------------------------- frames and compounds
def parallel_axis(inertia_com, mass: float, offset) -> np.ndarray:
    """Inertia about a point displaced by ``offset`` from the centre of mass (parallel-axis theorem,
    Steiner): I_P = I_com + m (|d|^2 E - d d^T)."""
    d = np.asarray(offset, dtype=np.float64).reshape(3)
    return np.asarray(inertia_com, dtype=np.float64) + mass * (float(np.sum(d * d)) * np.eye(3) - np.outer(d, d))


def transform_mass_properties(props: MassProperties, pose) -> MassProperties:
    """``props`` given in a shape frame S, re-expressed in frame F where ``pose`` (7,) is S's pose in F:
    com_F = p + R com_S, I_F = R I_S R^T."""
    pose = np.asarray(pose, dtype=np.float64).reshape(7)
    q = im.quat_normalize(pose[3:7])
    r = im.quat_to_mat3(q)
    # explicit 3x3 products, not BLAS (whose rounding depends on the CPU's kernel)
    inertia = im.mat3_mul(im.mat3_mul(r, np.ascontiguousarray(props.inertia, dtype=np.float64)), im.mat3_transpose(r))
    return MassProperties(props.mass, pose[:3] + im.mat3_vec(r, np.ascontiguousarray(props.com, dtype=np.float64)), inertia)


def compound_mass_properties(parts: Sequence[MassProperties], poses=None) -> MassProperties:
    """Sum of several parts, each with its pose (7,) in the compound's frame (identity when ``poses`` is
    None).  The inertia of each part is moved to the common centre of mass by the parallel-axis theorem."""
    if len(parts) == 0:
        raise ValueError("parts must hold at least one MassProperties")
    if poses is not None and len(poses) != len(parts):
        raise ValueError(f"poses must hold one pose per part ({len(parts)}); got {len(poses)}")
    moved = [transform_mass_properties(p, poses[i]) if poses is not None else p for i, p in enumerate(parts)]
    mass = sum(p.mass for p in moved)
    com = sum(p.mass * p.com for p in moved) / mass
    inertia = sum(parallel_axis(p.inertia, p.mass, p.com - com) for p in moved)
    return MassProperties(float(mass), com, 0.5 * (inertia + inertia.T))


def principal_frame(props: MassProperties) -> PrincipalFrame:
    """Principal moments (ascending) and the rotation R (body -> F) with R^T I R = diag(moments).

    R is a proper rotation (det +1); for repeated moments any orthonormal basis of the eigenspace is
    principal and the one returned is what the symmetric eigen solver gives."""
    moments, axes = np.linalg.eigh(props.inertia)
    if np.linalg.det(axes) < 0.0:
        axes[:, 2] = -axes[:, 2]
    if moments[0] <= 0.0:
        raise ValueError(f"inertia must be positive definite; got principal moments {moments.tolist()}")
    rotation = im.mat3_to_quat(np.ascontiguousarray(axes))
    return PrincipalFrame(props.mass, props.com.copy(), moments, rotation)
