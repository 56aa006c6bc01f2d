"""USD export: animated points (``UsdGeom.Points``) in a binary ``.usdc`` (or text ``.usda``) layer.

The stage holds ``/World`` (the default prim, an Xform) with one ``UsdGeom.Points`` per particle
group (``/World/Particles`` for a single group, ``/World/<group name>`` otherwise). Per frame, a
time sample of

``points``        positions (2-D scenes are written in the x-y plane, z = 0)
``velocities``    velocities, in units per second (USD motion blur reads them with
                  ``timeCodesPerSecond``)
``widths``        particle diameters (2 * radius); ``default_width`` where no radius was recorded
``ids``           the particle's slot index, stable across frames (for motion blur and
                  instancing when inactive slots are skipped)
``primvars:displayColor``  vertex colours, when colours are given

Stage metadata: ``startTimeCode`` / ``endTimeCode`` cover the frames (time code
``start_time_code + frame``, 1 default, as in Blender and Houdini timelines),
``timeCodesPerSecond`` = ``framesPerSecond`` = the state's output frame rate,
``upAxis`` (Z for 3-D scenes, as Inertia's gravity is -z; Y for 2-D scenes, which are y-up in
the x-y plane) and ``metersPerUnit`` (1.0: scene units are metres). Blender (Z-up) and
Houdini (Y-up) both convert from the stage's upAxis on import.

Requires usd-core (``pip install inertia[usd]``). Written atomically.

Reference: Pixar, Universal Scene Description, UsdGeom schema documentation (Points, Xform,
stage metrics).

Limitations: particles only; colliders are not exported. 2-D scenes are written in the x-y plane.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Callable

import numpy as np

from .atomic import atomic_path

__all__ = ["write_usd", "write_usd_bodies"]


def _import_usd():
    try:
        from pxr import Sdf, Usd, UsdGeom, Vt  # noqa: F401
    except ImportError as error:  # pragma: no cover - depends on the environment
        raise ImportError("USD export needs usd-core: pip install inertia[usd]  (or: pip install usd-core)") from error
    from pxr import Sdf, Usd, UsdGeom, Vt

    return Sdf, Usd, UsdGeom, Vt


def _prim_name(name: str) -> str:
    # USD prim names: letters, digits and underscores, not starting with a digit.
    clean = "".join(c if (c.isalnum() or c == "_") else "_" for c in str(name)) or "group"
    return clean if not clean[0].isdigit() else "_" + clean


def write_usd(
    states,
    path: str | os.PathLike,
    *,
    colors: np.ndarray | Callable[[int], np.ndarray] | None = None,
    default_width: float = 0.02,
    up_axis: str | None = None,
    meters_per_unit: float = 1.0,
    fps: float | None = None,
    start_time_code: float = 1.0,
    active_only: bool = True,
    frames=None,
) -> Path:
    """Write a `States` as animated USD points (see the module docstring). Returns the path.

    ``colors``: (N, 3) or (F, N, 3) floats in [0, 1] or uint8, or ``colors(frame) -> (N, 3)``.
    ``fps``: time codes per second; default the state's frame rate (24 if unknown).
    ``up_axis``: "Z" or "Y"; default Z for 3-D, Y for 2-D states.
    ``frames``: a slice or index array of frames to write (default all).
    """
    Sdf, Usd, UsdGeom, Vt = _import_usd()
    path = Path(path)
    if path.suffix.lower() not in (".usd", ".usdc", ".usda"):
        raise ValueError(f"write_usd: {path} must end in .usdc, .usda or .usd")
    if up_axis is None:
        up_axis = "Z" if states.dim == 3 else "Y"
    if up_axis.upper() not in ("Y", "Z"):
        raise ValueError(f"write_usd: up_axis must be 'Y' or 'Z', got {up_axis!r}")
    rate = float(fps or states.fps or 24.0)
    indices = np.atleast_1d(np.arange(states.frame_count)[slice(None) if frames is None else frames])

    # Groups: one Points prim each.
    group_of = states.groups()
    names = list(states.metadata.get("groups") or [])
    if group_of is None:
        group_of = np.zeros(states.particle_count, dtype=np.int32)
    group_ids = np.unique(group_of) if states.particle_count else np.zeros(0, np.int32)
    if len(group_ids) <= 1:
        prim_names = {int(g): "Particles" for g in group_ids} or {0: "Particles"}
    else:
        prim_names = {int(g): _prim_name(names[g] if g < len(names) else f"group_{g}") for g in group_ids}

    def as_vec3f(array):
        array = np.asarray(array, dtype=np.float32)
        if array.shape[1] == 2:
            array = np.concatenate([array, np.zeros((array.shape[0], 1), np.float32)], axis=1)
        return Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(array))

    with atomic_path(path) as temp:
        stage = Usd.Stage.CreateNew(str(temp))
        UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y if up_axis.upper() == "Y" else UsdGeom.Tokens.z)
        UsdGeom.SetStageMetersPerUnit(stage, float(meters_per_unit))
        stage.SetTimeCodesPerSecond(rate)
        stage.SetFramesPerSecond(rate)
        stage.SetStartTimeCode(float(start_time_code))
        stage.SetEndTimeCode(float(start_time_code + max(len(indices) - 1, 0)))
        world = UsdGeom.Xform.Define(stage, "/World")
        stage.SetDefaultPrim(world.GetPrim())
        stage.GetRootLayer().documentation = "Written by inertia from a state file"

        prims, primvars = {}, {}
        for g, name in prim_names.items():
            points = UsdGeom.Points.Define(stage, f"/World/{name}")
            points.CreateWidthsAttr()
            points.SetWidthsInterpolation(UsdGeom.Tokens.vertex)
            prims[g] = points
            if colors is not None:
                primvars[g] = points.CreateDisplayColorPrimvar(UsdGeom.Tokens.vertex)

        for k, f in enumerate(indices):
            f = int(f)
            code = Usd.TimeCode(float(start_time_code + k))
            active = states.active(f) if active_only else None
            radius = states.radius(f)
            widths = np.full(states.particle_count, default_width, np.float32) if radius is None else 2.0 * np.asarray(radius, np.float32)
            widths = np.where(widths > 0, widths, default_width).astype(np.float32)
            frame_colors = colors(f) if callable(colors) else colors
            if frame_colors is not None and np.ndim(frame_colors) == 3:
                frame_colors = frame_colors[f]
            if frame_colors is not None:
                frame_colors = np.asarray(frame_colors)
                frame_colors = frame_colors / 255.0 if frame_colors.dtype == np.uint8 else frame_colors
            for g, points in prims.items():
                sel = group_of == g
                if active is not None:
                    sel = sel & np.asarray(active, dtype=bool)
                ids = np.flatnonzero(sel)
                points.GetPointsAttr().Set(as_vec3f(states.positions[f][sel]), code)
                if states.velocities is not None:
                    points.GetVelocitiesAttr().Set(as_vec3f(states.velocities[f][sel]), code)
                points.GetWidthsAttr().Set(Vt.FloatArray.FromNumpy(np.ascontiguousarray(widths[sel])), code)
                points.GetIdsAttr().Set(Vt.Int64Array.FromNumpy(ids.astype(np.int64)), code)
                if frame_colors is not None:
                    primvars[g].Set(as_vec3f(frame_colors[sel]), code)
        stage.GetRootLayer().Save()
        del stage
    return path


def write_usd_bodies(path: str | os.PathLike, model, body_q_frames, *, fps: float = 30.0,
                     start_time_code: float = 1.0, up_axis: str = "Z", segments: int = 24) -> Path:
    """Write rigid bodies as an animated USD stage (see `inertia.io.obj` for the tessellation).

    ``/World/Bodies/<body name>``: an Xform per body with time-sampled ``xformOp:translate`` (double3,
    centre of mass, m) and ``xformOp:orient`` (quatd w, x, y, z) per time code ``start_time_code + frame``;
    under it a ``UsdGeom.Mesh`` per shape with its constant local pose. ``/World/Static/shape_S``: static
    shapes (body -1) as meshes in world coordinates. ``model``: a `Model` or a ``States.model`` dict;
    ``body_q_frames (F, B, 7)``. Returns the path.
    """
    from pxr import Gf

    from .obj import model_arrays, shape_meshes

    Sdf, Usd, UsdGeom, Vt = _import_usd()
    path = Path(path)
    if path.suffix.lower() not in (".usd", ".usdc", ".usda"):
        raise ValueError(f"write_usd_bodies: {path} must end in .usdc, .usda or .usd")
    if up_axis.upper() not in ("Y", "Z"):
        raise ValueError(f"write_usd_bodies: up_axis must be 'Y' or 'Z', got {up_axis!r}")
    frames = np.asarray(body_q_frames, dtype=np.float64)
    m = model_arrays(model)
    nb = frames.shape[1] if frames.ndim == 3 else 0
    meshes = shape_meshes(m, segments=segments)
    names = m.get("body_name") or [f"body{i}" for i in range(nb)]

    def quatd(q):
        return Gf.Quatd(float(q[0]), Gf.Vec3d(float(q[1]), float(q[2]), float(q[3])))

    def mesh_prim(stage, prim_path, verts, faces):
        mesh = UsdGeom.Mesh.Define(stage, prim_path)
        mesh.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(verts, np.float32)))
        mesh.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.full(len(faces), 3, np.int32)))
        mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(np.ascontiguousarray(faces.ravel(), np.int32)))
        mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
        return mesh

    with atomic_path(path) as temp:
        stage = Usd.Stage.CreateNew(str(temp))
        UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y if up_axis.upper() == "Y" else UsdGeom.Tokens.z)
        UsdGeom.SetStageMetersPerUnit(stage, 1.0)
        stage.SetTimeCodesPerSecond(float(fps))
        stage.SetFramesPerSecond(float(fps))
        stage.SetStartTimeCode(float(start_time_code))
        stage.SetEndTimeCode(float(start_time_code + max(len(frames) - 1, 0)))
        world = UsdGeom.Xform.Define(stage, "/World")
        stage.SetDefaultPrim(world.GetPrim())
        UsdGeom.Xform.Define(stage, "/World/Bodies")
        UsdGeom.Xform.Define(stage, "/World/Static")
        used = set()
        body_prims = []
        for b in range(nb):
            name = _prim_name(names[b] if b < len(names) else f"body{b}")
            while name in used:
                name += "_"
            used.add(name)
            xf = UsdGeom.Xform.Define(stage, f"/World/Bodies/{name}")
            translate = xf.AddTranslateOp(UsdGeom.XformOp.PrecisionDouble)
            orient = xf.AddOrientOp(UsdGeom.XformOp.PrecisionDouble)
            body_prims.append((xf, translate, orient))
        for si, (verts, faces) in enumerate(meshes):
            b = int(m["shape_body"][si])
            pose = np.asarray(m["shape_local_pose"][si], float)
            if b < 0:
                mesh = mesh_prim(stage, f"/World/Static/shape_{si}", verts, faces)
            else:
                mesh = mesh_prim(stage, f"{body_prims[b][0].GetPath()}/shape_{si}", verts, faces)
            mesh.AddTranslateOp(UsdGeom.XformOp.PrecisionDouble).Set(Gf.Vec3d(*map(float, pose[:3])))
            mesh.AddOrientOp(UsdGeom.XformOp.PrecisionDouble).Set(quatd(pose[3:]))
        for k, q in enumerate(frames):
            code = Usd.TimeCode(float(start_time_code + k))
            for b, (_, translate, orient) in enumerate(body_prims):
                translate.Set(Gf.Vec3d(*map(float, q[b, :3])), code)
                orient.Set(quatd(q[b, 3:]), code)
        stage.GetRootLayer().Save()
        del stage
    return path
