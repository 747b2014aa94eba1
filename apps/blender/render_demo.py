"""Render ``make demo`` in Blender: source and its cage | target | result and its deformed cage.

Headless, Cycles on the CPU, with Blender as a Python module (``make blender-venv``)::

    .venv-blender/bin/python apps/blender/render_demo.py --out out/blender_demo.png

The demo's chairs are read with cagekit's reader (``cagekit.io.load_mesh``, vertices exactly
as in the files) into Blender objects; the add-on's own operators then make the pictured
cage and result: ``cagekit.fit_cage`` cages the source, ``cagekit.deform_to_target`` (from
that cage, with ``symmetry="x"`` as ``make demo``) makes ``chair_source_deformed`` and its
deformed cage.
The operators see the files' coordinates (y up, as the CLI does); only afterwards are the
objects turned z up and set side by side for the picture. Cages are rendered as thin
orange wireframes (a Wireframe modifier). The PNG is written atomically (rendered to a
temporary file beside it, then renamed).
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import tempfile
import time
from pathlib import Path

import bpy
import numpy as np
from mathutils import Euler, Matrix, Vector

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
for _path in (ROOT, HERE):
    if str(_path) not in sys.path:
        sys.path.insert(0, str(_path))

SOURCE = ROOT / "data" / "example" / "chair_source.obj"
TARGET = ROOT / "data" / "example" / "chair_target.obj"
DEFAULT_OUT = ROOT / "out" / "blender_demo.png"

CHAIR_RGB = (0.16, 0.30, 0.58)
CAGE_RGB = (0.95, 0.22, 0.01)
GROUND_RGB = (0.80, 0.80, 0.80)
TEXT_RGB = (0.02, 0.02, 0.02)
TURN = math.radians(-28)  # each chair turned about its own vertical axis, three-quarter view
ELEVATION = math.radians(17)  # the camera looks down this much
LENS = 70.0  # mm on a 36 mm sensor: little perspective
GAP = 0.22  # m between neighbouring groups
CAGE_WIRE = 0.005  # m, the cages' wire thickness
LOOK = "AgX - Medium High Contrast"


def parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", default=str(DEFAULT_OUT), help="PNG to write (default: %(default)s)")
    p.add_argument("--samples", type=int, default=32,
                   help="Cycles samples a pixel, denoised with OpenImageDenoise when built in "
                        "(default: %(default)s)")
    p.add_argument("--size", default="1500x500", help="WxH in pixels (default: %(default)s)")
    p.add_argument("--faces", type=int, default=200, help="cage faces (default: %(default)s)")
    p.add_argument("--no-labels", action="store_true", help="leave out the three labels")
    args = p.parse_args(argv)
    try:
        w, h = (int(x) for x in args.size.lower().split("x"))
        if w < 16 or h < 16:
            raise ValueError
    except ValueError:
        p.error(f"--size takes WxH, both at least 16, e.g. 1500x500 (got {args.size!r})")
    if args.samples < 1:
        p.error("--samples must be at least 1")
    args.width, args.height = w, h
    return args


# ----------------------------------------------------------------------------- the scene

def mesh_from_file(path: Path, name: str):
    """A mesh object from ``path`` read by cagekit (every vertex, in file order)."""
    from cagekit_blender import meshes

    from cagekit.io import load_mesh

    V, F = load_mesh(path)
    obj = meshes.new_object(name, V, F, bpy.context.scene.collection)
    for poly in obj.data.polygons:  # flat shading: the chairs are boards and bars
        poly.use_smooth = False
    return obj


def select(active, *others) -> None:
    view_layer = bpy.context.view_layer
    for o in view_layer.objects:
        o.select_set(False)
    for o in (*others, active):
        o.select_set(True)
    view_layer.objects.active = active


def run_operator(op, **kwargs):
    """Call an add-on operator; its error report (a RuntimeError in background mode) or
    any result but FINISHED stops the script with the add-on's own words."""
    try:
        result = op(**kwargs)
    except RuntimeError as exc:
        sys.exit(f"render_demo: {op.idname_py()} failed: {' '.join(str(exc).split())}")
    if result != {"FINISHED"}:
        sys.exit(f"render_demo: {op.idname_py()} returned {result}")


def make_cagekit_objects(faces: int):
    """The add-on at work: source and target read in, the source's cage, the result and its
    deformed cage. Returns the five objects."""
    import cagekit_blender

    cagekit_blender.register()
    source = mesh_from_file(SOURCE, "chair_source")
    target = mesh_from_file(TARGET, "chair_target")

    select(source)
    t = time.perf_counter()
    run_operator(bpy.ops.cagekit.fit_cage, faces=faces)
    cage = bpy.data.objects["chair_source_cage"]
    print(f"render_demo: cagekit.fit_cage: {len(cage.data.polygons)} faces "
          f"({time.perf_counter() - t:.1f} s)")

    select(target, source)  # the source selected, the target active
    t = time.perf_counter()
    run_operator(bpy.ops.cagekit.deform_to_target, cage=cage.name, symmetry="x")
    result = bpy.data.objects["chair_source_deformed"]
    result_cage = bpy.data.objects["chair_source_deformed_cage"]
    print(f"render_demo: cagekit.deform_to_target: {len(result_cage.data.polygons)} cage "
          f"faces ({time.perf_counter() - t:.1f} s)")
    return source, cage, target, result, result_cage


def material(name: str, rgb, *, roughness=0.5, emission=0.0):
    mat = bpy.data.materials.new(name)
    if mat.node_tree is None:  # Blender before 5.0
        mat.use_nodes = True
    bsdf = next(n for n in mat.node_tree.nodes if n.type == "BSDF_PRINCIPLED")
    bsdf.inputs["Base Color"].default_value = (*rgb, 1.0)
    bsdf.inputs["Roughness"].default_value = roughness
    if emission:
        bsdf.inputs["Emission Color"].default_value = (*rgb, 1.0)
        bsdf.inputs["Emission Strength"].default_value = emission
    mat.diffuse_color = (*rgb, 1.0)
    return mat


def set_material(obj, mat) -> None:
    obj.data.materials.clear()
    obj.data.materials.append(mat)


def show_as_wire(cage, mat) -> None:
    """A cage as thin, orange, shadowless wires in the render (the add-on hides cages
    from renders and shows them as wireframes in the viewport only)."""
    cage.hide_render = False
    mod = cage.modifiers.new("wire", "WIREFRAME")
    mod.thickness = CAGE_WIRE
    mod.use_even_offset = True
    mod.use_replace = True
    set_material(cage, mat)
    cage.visible_shadow = False


def world_points(objects) -> np.ndarray:
    """(n, 3): every vertex of ``objects`` (evaluated: modifiers applied) in world space."""
    bpy.context.view_layer.update()
    depsgraph = bpy.context.evaluated_depsgraph_get()
    out = []
    for obj in objects:
        ev = obj.evaluated_get(depsgraph)
        if obj.type == "MESH":
            mesh = ev.to_mesh()
            co = np.empty(3 * len(mesh.vertices), dtype=np.float32)
            mesh.vertices.foreach_get("co", co)
            ev.to_mesh_clear()
            co = co.reshape(-1, 3).astype(np.float64)
        else:  # text: its bounding box
            co = np.array([tuple(c) for c in ev.bound_box], dtype=np.float64)
        M = np.array(ev.matrix_world, dtype=np.float64)
        out.append(co @ M[:3, :3].T + M[:3, 3])
    return np.concatenate(out)


def arrange(groups):
    """Turn every object z up (the files are y up), turn each group a little about its
    own vertical axis and set the groups side by side along x, all standing on z = 0."""
    y_up_to_z_up = Matrix.Rotation(math.radians(90), 4, "X")
    turn = Matrix.Rotation(TURN, 4, "Z")
    placed, x_right = [], None
    for group in groups:
        for obj in group:
            obj.matrix_world = turn @ y_up_to_z_up
        P = world_points(group[:1])  # the chair decides the place, not its cage
        center = P.mean(axis=0)
        Q = world_points(group)
        half_left, half_right = center[0] - Q[:, 0].min(), Q[:, 0].max() - center[0]
        x = 0.0 if x_right is None else x_right + GAP + half_left
        shift = Matrix.Translation((x - center[0], -center[1], -P[:, 2].min()))
        for obj in group:
            obj.matrix_world = shift @ obj.matrix_world
        x_right = x + half_right
        placed.append(x)
    # the middle group at x = 0
    mid = placed[len(placed) // 2]
    for group in groups:
        for obj in group:
            obj.matrix_world = Matrix.Translation((-mid, 0, 0)) @ obj.matrix_world
    return [x - mid for x in placed]


def label(text: str, x: float, z: float, rotation, mat):
    curve = bpy.data.curves.new(f"label_{text}", "FONT")
    curve.body = text
    curve.align_x = "CENTER"
    curve.align_y = "BOTTOM"
    curve.size = 0.10
    obj = bpy.data.objects.new(f"label_{text}", curve)
    bpy.context.scene.collection.objects.link(obj)
    obj.location = (x, 0.0, z)
    obj.rotation_euler = rotation
    obj.data.materials.append(mat)
    obj.visible_shadow = False
    return obj


def add_ground(mat):
    mesh = bpy.data.meshes.new("ground")
    s = 50.0
    mesh.from_pydata([(-s, -s, 0), (s, -s, 0), (s, s, 0), (-s, s, 0)], [], [(0, 1, 2, 3)])
    obj = bpy.data.objects.new("ground", mesh)
    bpy.context.scene.collection.objects.link(obj)
    set_material(obj, mat)
    return obj


def add_lights(scene):
    world = bpy.data.worlds.new("world")
    if world.node_tree is None:  # Blender before 5.0
        world.use_nodes = True
    bg = world.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (0.85, 0.87, 0.90, 1.0)
    bg.inputs["Strength"].default_value = 0.7
    scene.world = world
    sun = bpy.data.lights.new("sun", "SUN")
    sun.energy = 2.6
    sun.angle = math.radians(12)  # soft shadows
    obj = bpy.data.objects.new("sun", sun)
    obj.rotation_euler = Euler((math.radians(42), 0.0, math.radians(-38)))
    scene.collection.objects.link(obj)


def add_camera(scene, points, width, height, margin=0.94):
    """A camera looking down ``ELEVATION`` from the front (-y) framing ``points``: moved
    back just far enough, its lens shifted to centre them."""
    cam_data = bpy.data.cameras.new("camera")
    cam_data.lens = LENS
    cam_data.sensor_width = 36.0
    cam_data.sensor_fit = "HORIZONTAL"
    cam = bpy.data.objects.new("camera", cam_data)
    scene.collection.objects.link(cam)
    scene.camera = cam
    rot = Euler((math.radians(90) - ELEVATION, 0.0, 0.0))
    cam.rotation_euler = rot
    R = np.array(rot.to_matrix(), dtype=np.float64)
    center = 0.5 * (points.min(axis=0) + points.max(axis=0))
    q = (points - center) @ R  # camera coordinates with the camera at the centre
    tx = 18.0 / LENS
    ty = tx * height / width

    def spans(d):
        depth = d - q[:, 2]
        u, v = q[:, 0] / depth / tx, q[:, 1] / depth / ty
        return (u.max() - u.min()) / 2, (v.max() - v.min()) / 2, u, v

    lo = float(q[:, 2].max()) + 1e-3
    hi = lo + 100.0
    for _ in range(60):  # the closest distance at which the centred points fit
        d = 0.5 * (lo + hi)
        su, sv, _, _ = spans(d)
        lo, hi = (d, hi) if max(su, sv) > margin else (lo, d)
    _, _, u, v = spans(hi)
    # Blender's shift is in units of the sensor's width (the larger side here)
    cam_data.shift_x = 0.5 * (u.max() + u.min()) / 2
    cam_data.shift_y = 0.5 * (v.max() + v.min()) / 2 * height / width
    forward = R @ np.array([0.0, 0.0, -1.0])
    cam.location = Vector(center - hi * forward)
    return cam


def render_settings(scene, args) -> None:
    import _cycles

    scene.render.engine = "CYCLES"
    cy = scene.cycles
    cy.device = "CPU"
    cy.samples = args.samples
    cy.use_adaptive_sampling = True
    cy.use_denoising = bool(getattr(_cycles, "with_openimagedenoise", False))
    if cy.use_denoising:
        cy.denoiser = "OPENIMAGEDENOISE"
    cy.max_bounces = 4
    cy.diffuse_bounces = 2
    cy.glossy_bounces = 2
    cy.transparent_max_bounces = 4
    cy.transmission_bounces = 0
    cy.volume_bounces = 0
    scene.render.resolution_x, scene.render.resolution_y = args.width, args.height
    scene.render.resolution_percentage = 100
    scene.render.film_transparent = False
    scene.render.image_settings.file_format = "PNG"
    scene.render.image_settings.color_mode = "RGB"
    scene.render.image_settings.color_depth = "8"
    scene.render.image_settings.compression = 90
    scene.view_settings.view_transform = "AgX"
    try:
        scene.view_settings.look = LOOK
    except TypeError:  # a Blender without this look: AgX's own
        scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0


def render_to(scene, out: Path) -> None:
    """Render ``scene`` into ``out`` atomically: a temporary PNG beside it, renamed."""
    out.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{out.stem}.", suffix=".png", dir=out.parent)
    os.close(fd)
    try:
        scene.render.filepath = tmp
        scene.render.use_file_extension = False
        bpy.ops.render.render(write_still=True)
        if os.path.getsize(tmp) == 0:
            raise RuntimeError("Blender wrote no image")
        os.replace(tmp, out)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)


def main(argv=None) -> None:
    args = parse_args(argv)
    out = Path(args.out).resolve()
    start = time.perf_counter()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene

    source, cage, target, result, result_cage = make_cagekit_objects(args.faces)

    chair_mat = material("chair", CHAIR_RGB, roughness=0.55)
    cage_mat = material("cage", CAGE_RGB, roughness=0.6, emission=0.6)
    for obj in (source, target, result):
        set_material(obj, chair_mat)
    for obj in (cage, result_cage):
        show_as_wire(obj, cage_mat)
    groups = [(source, cage), (target,), (result, result_cage)]
    xs = arrange(groups)

    shown = [o for g in groups for o in g]
    if not args.no_labels:
        text_mat = material("text", TEXT_RGB, roughness=0.8)
        top = world_points(shown)[:, 2].max()
        rot = Euler((math.radians(90) - ELEVATION, 0.0, 0.0))
        for name, x in zip(("source", "target", "result"), xs):
            shown.append(label(name, x, top + 0.08, rot, text_mat))
    add_ground(material("ground", GROUND_RGB, roughness=0.9))
    add_lights(scene)
    add_camera(scene, world_points(shown), args.width, args.height)
    render_settings(scene, args)

    t = time.perf_counter()
    render_to(scene, out)
    print(f"render_demo: wrote {out} ({args.width}x{args.height}, {args.samples} samples, "
          f"render {time.perf_counter() - t:.0f} s, in all {time.perf_counter() - start:.0f} s)")


if __name__ == "__main__":
    main()
