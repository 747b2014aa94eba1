"""The add-on's operators: ``bpy.ops.cagekit.<name>()``, each with its options as properties.

Every computation is cagekit's own (``cagekit.fit_cage``, ``cagekit.bind``,
``cagekit.deform``, ``cagekit.transfer``, ``cagekit.batch.amplify``); these operators
only read the scene, call it (:mod:`.jobs`) and add the results. Results are new objects
(copies of the source, so materials, UVs and polygons are kept, with moved vertices);
inputs are never changed, except by ``bind`` and ``unbind``, which are undoable.
"""

from __future__ import annotations

import os
import tempfile
import warnings

import bpy
from bpy.props import EnumProperty, IntProperty, StringProperty

from cagekit.errors import InputError

from . import jobs, live, meshes

COORDS_ITEMS = [("mvc", "Mean value", "Affine-invariant; the default everywhere"),
                ("green", "Green", "Exact for similarities; details keep their proportions "
                                   "under stretch")]


def _coords_property():
    return EnumProperty(name="Coordinates", items=COORDS_ITEMS, default="mvc")


def _copy_with(obj, name: str, V, collection):
    """A copy of mesh object ``obj`` (its own mesh data) named ``name`` with world-space
    vertices ``V``, linked to ``collection``."""
    new = obj.copy()
    new.data = obj.data.copy()
    new.name = new.data.name = name
    new.animation_data_clear()
    live.forget(new)
    new.modifiers.clear()
    collection.objects.link(new)
    meshes.set_world_vertices(new, V)
    return new


def _new_collection(name: str, context):
    coll = bpy.data.collections.new(name)
    context.scene.collection.children.link(coll)
    return coll


def _select_only(context, objects) -> None:
    for o in context.view_layer.objects:
        o.select_set(False)
    for o in objects:
        o.select_set(True)
    if objects:
        context.view_layer.objects.active = objects[-1]


class CAGEKIT_OT_fit_cage(jobs.Job, bpy.types.Operator):
    """Build a cage around the active mesh (cagekit.fit_cage), shown as a wireframe"""

    bl_idname = "cagekit.fit_cage"
    bl_label = "Fit Cage"
    label = "fitting a cage"

    faces: IntProperty(name="Faces", default=200, min=80, max=10_000,
                       description="Largest number of cage faces")
    method: EnumProperty(name="Method", default="wrap", items=[
        ("wrap", "Wrap", "Alpha wrap, decimated, repaired until it encloses the mesh"),
        ("template", "Template", "A sphere template fitted around the mesh (80 faces)")])

    def gather(self, context):
        obj = meshes.mesh_object(context.active_object, "the mesh to cage")
        return obj.name, *meshes.world_mesh(obj, "the mesh to cage")

    def compute(self, inputs, progress):
        from cagekit import fit_cage

        name, V, F = inputs
        progress(0, 1, name)
        cage = fit_cage(V, F, faces=self.faces, method=self.method, report=False)
        return name, (cage.vertices, cage.faces)

    def apply(self, context, result):
        name, (cage_v, cage_f) = result
        obj = bpy.data.objects[name]
        cage = meshes.new_object(f"{name}_cage", cage_v, cage_f, meshes.home_collection(obj),
                                 wire=True)
        _select_only(context, [cage])
        self.report({"INFO"}, f"cagekit: {cage.name}, {len(cage_f)} faces")


class CAGEKIT_OT_bind(jobs.Job, bpy.types.Operator):
    """Bind the selected meshes to the active cage: editing the cage then moves them"""

    bl_idname = "cagekit.bind"
    bl_label = "Bind to Cage"
    label = "binding"

    coords: _coords_property()

    def gather(self, context):
        from cagekit.cage import check_cage

        targets, cage = jobs.selected_and_active(context, "meshes to bind", "cage")
        cage_v, cage_f = meshes.world_mesh(cage, "the cage")
        try:
            cage_f = check_cage(cage_v, cage_f)
        except InputError as exc:
            raise type(exc)(f"cage {cage.name!r}: {exc}") from None
        shapes = [(o.name, meshes.world_mesh(o, "the mesh to bind")[0]) for o in targets]
        return cage.name, cage_v, cage_f, shapes

    def compute(self, inputs, progress):
        from cagekit.coords import bind
        from cagekit.coords.binding import warn_outside

        cage_name, cage_v, cage_f, shapes = inputs
        out = []
        for i, (name, V) in enumerate(shapes):
            progress(i, len(shapes), name)
            # gather checked the cage; MVC gives the winding numbers in the same pass
            binding = bind(V, cage_v, cage_f, method=self.coords, check=False, winding=True)
            with warnings.catch_warnings(record=True) as caught:  # as the commands warn
                warnings.simplefilter("always")
                warn_outside(V, cage_v, cage_f, shape=name, cage=cage_name,
                             winding=binding.winding)
            out.append((name, binding, [str(w.message) for w in caught]))
        return cage_name, out

    def apply(self, context, result):
        cage_name, bound = result
        cage = bpy.data.objects[cage_name]
        for name, binding, warned in bound:
            obj = bpy.data.objects[name]
            if live.is_bound(obj):
                live.unbind_object(obj)
            live.bind_object(obj, cage, self.coords, binding)
            for text in warned:
                self.report({"WARNING"}, f"cagekit: {text}")
        self.report({"INFO"}, f"cagekit: {len(bound)} mesh(es) bound to {cage_name}")


class CAGEKIT_OT_unbind(bpy.types.Operator):
    """Give the selected bound meshes back their rest shape and forget their cage"""

    bl_idname = "cagekit.unbind"
    bl_label = "Unbind"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        bound = [o for o in context.selected_objects if live.is_bound(o)]
        if not bound:
            self.report({"ERROR"}, "no bound mesh selected")
            return {"CANCELLED"}
        for obj in bound:
            live.unbind_object(obj)
        self.report({"INFO"}, f"cagekit: {len(bound)} mesh(es) unbound")
        return {"FINISHED"}


class CAGEKIT_OT_deform_to_target(jobs.Job, bpy.types.Operator):
    """A copy of the selected source with the active target's proportions (cagekit.deform),
    with its deformed cage"""

    bl_idname = "cagekit.deform_to_target"
    bl_label = "Deform to Target"
    label = "deforming"

    cage: StringProperty(name="Cage", description="The source's cage (an object); empty: "
                         "the cage the source is bound to, else one fitted here")
    faces: IntProperty(name="Cage faces", default=200, min=80, max=10_000,
                       description="Face budget of a cage fitted here")
    symmetry: EnumProperty(name="Symmetry", default="none", items=[
        ("none", "None", ""), ("x", "X", "Symmetric about the plane normal to x"),
        ("y", "Y", ""), ("z", "Z", "")])
    coords: _coords_property()
    evaluations: IntProperty(name="Evaluations", default=60, min=1, max=10_000,
                             description="Energy evaluations of the optimiser")
    seed: IntProperty(name="Seed", default=0, min=0)

    def gather(self, context):
        sources, target = jobs.selected_and_active(context, "source", "target")
        if len(sources) != 1:
            raise InputError(f"select one source (selected: {len(sources)})")
        source = sources[0]
        cage = (_object(self.cage, "cage") if self.cage
                else source.cagekit_cage if live.is_bound(source) else None)
        return (source.name, meshes.world_mesh(source, "the source"),
                meshes.world_mesh(target, "the target"),
                None if cage is None else meshes.world_mesh(cage, f"cage {cage.name!r}"))

    def compute(self, inputs, progress):
        from cagekit import DeformOptions, deform

        name, source, target, cage = inputs
        options = DeformOptions(
            faces=self.faces, coords=self.coords,
            symmetry=None if self.symmetry == "none" else self.symmetry,
            max_evaluations=self.evaluations, seed=self.seed)
        return name, cage is None, deform(
            *source, *target, *((None, None) if cage is None else cage), options=options,
            progress=lambda i, n: progress(i, n, "evaluations"))

    def apply(self, context, result):
        name, fitted, res = result
        source = bpy.data.objects[name]
        home = meshes.home_collection(context.active_object)
        out = _copy_with(source, f"{name}_deformed", res.vertices, home)
        made = [meshes.new_object(f"{name}_deformed_cage", res.deformed_cage_v, res.cage_f,
                                  home, wire=True), out]
        if fitted:  # the cage the deformation started from, beside the source
            made.insert(0, meshes.new_object(f"{name}_cage", res.cage_v, res.cage_f,
                                             meshes.home_collection(source), wire=True))
        _select_only(context, made)
        self.report({"INFO"}, f"cagekit: {out.name} in {res.seconds:.1f} s "
                              f"({res.iterations} evaluations)")


def _object(name: str, role: str):
    obj = bpy.data.objects.get(name) if name else None
    if obj is None:
        raise InputError(f"no {role}: name an object" if not name
                           else f"{role} {name!r} is not an object of this file")
    return meshes.mesh_object(obj, role)


class CAGEKIT_OT_transfer_pose(jobs.Job, bpy.types.Operator):
    """Carry the template's poses to a character by matching landmarks
    (cagekit.transfer): one posed copy of the character per pose"""

    bl_idname = "cagekit.transfer_pose"
    bl_label = "Transfer Pose"
    label = "transferring"

    template: StringProperty(name="Template", description="The template in rest pose")
    template_cage: StringProperty(name="Template cage")
    poses: StringProperty(name="Poses", description="A collection of the template posed")
    character: StringProperty(name="Character", description="The character in rest pose")
    landmarks: EnumProperty(name="Landmarks", default="groups", items=[
        ("groups", "Vertex groups", "Each vertex group of template and character is a "
                                    "landmark, at the weighted mean of its vertices"),
        ("files", "Files", "Landmark files (.picked, .json or .csv)")])
    template_landmarks: StringProperty(name="Template landmarks", subtype="FILE_PATH")
    character_landmarks: StringProperty(name="Character landmarks", subtype="FILE_PATH")
    rule: EnumProperty(name="Rule", default="pose", items=[
        ("pose", "Pose", "The template's joint rotations, whatever the character's rest pose"),
        ("offsets", "Offsets", "The paper's C_c + A (C_st - C_s)")])
    coords: _coords_property()
    seed: IntProperty(name="Seed", default=0, min=0)

    def gather(self, context):
        from cagekit.io.landmarks import load_landmarks

        template = _object(self.template, "template")
        cage = _object(self.template_cage, "template cage")
        character = _object(self.character, "character")
        coll = bpy.data.collections.get(self.poses)
        if coll is None:
            raise InputError(f"poses: {self.poses!r} is not a collection of this file")
        poses = [o for o in coll.objects if o.type == "MESH"]
        if not poses:
            raise InputError(f"collection {coll.name!r} holds no mesh")
        if self.landmarks == "files":
            marks = [load_landmarks(bpy.path.abspath(p))
                     for p in (self.template_landmarks, self.character_landmarks)]
        else:
            marks = [meshes.landmarks_of(o) for o in (template, character)]
        return (meshes.world_mesh(template, "template"), meshes.world_mesh(cage, "template cage"),
                meshes.world_mesh(character, "character"), character.name,
                [(p.name, meshes.world_mesh(p, "pose")) for p in poses], marks)

    def compute(self, inputs, progress):
        from cagekit.transfer import character as dt

        (Vt, Ft), (cv, cf), (Vc, Fc), name, poses, (marks_t, marks_c) = inputs
        progress(0, len(poses) + 1, "fitting the character's cage")
        char = dt.fit_character(Vt, cv, cf, marks_t, Vc, Fc, marks_c, coords=self.coords,
                                template_name=self.template, character_name=name)
        fitter = dt.classical_fitter(Vt, cv, cf)
        out = []
        for i, (pose_name, pose) in enumerate(poses):
            progress(i + 1, len(poses) + 1, pose_name)
            C = dt.template_cage_classical(Vt, Ft, cv, cf, *pose, seed=self.seed,
                                           fitter=fitter)
            out.append((pose_name, dt.transfer(char, C, self.rule)))
        return name, char, out

    def apply(self, context, result):
        name, char, posed = result
        character = bpy.data.objects[name]
        coll = _new_collection(f"{name}_poses", context)
        meshes.new_object(f"{name}_cage", char.cage_v, char.cage_f, coll, wire=True)
        made = [_copy_with(character, f"{name}_{pose}", X, coll) for pose, X in posed]
        _select_only(context, made)
        self.report({"INFO"}, f"cagekit: {len(made)} pose(s) of {name} in {coll.name}")


class CAGEKIT_OT_amplify(jobs.Job, bpy.types.Operator):
    """Variations of a collection of meshes (cagekit.batch.amplify): each source deformed onto
    another's proportions, the implausible ones left out, into a new collection"""

    bl_idname = "cagekit.amplify"
    bl_label = "Amplify"
    label = "making variations"

    collection: StringProperty(name="Collection", description="The meshes to vary")
    variations: IntProperty(name="Variations", default=4, min=1, max=10_000)
    coords: _coords_property()
    seed: IntProperty(name="Seed", default=0, min=0)

    def gather(self, context):
        coll = bpy.data.collections.get(self.collection)
        if coll is None:
            raise InputError(f"{self.collection!r} is not a collection of this file")
        objects = [o for o in coll.objects if o.type == "MESH"]
        if len(objects) < 2:
            raise InputError(f"collection {coll.name!r} needs at least 2 meshes "
                               f"(has {len(objects)})")
        names = [o.name for o in objects]
        if len({_file_name(n) for n in names}) < len(names):
            raise InputError("two meshes of the collection have names that differ only "
                               "in characters a file name cannot hold: rename one")
        return coll.name, [(o.name, meshes.world_mesh(o, "mesh")) for o in objects]

    def compute(self, inputs, progress):
        from cagekit import io
        from cagekit.batch.amplify import amplify

        coll, shapes = inputs
        by_file = {_file_name(name): name for name, _ in shapes}
        with tempfile.TemporaryDirectory(prefix="cagekit_amplify_") as tmp:
            folder = os.path.join(tmp, "collection")
            os.makedirs(folder)
            for name, (V, F) in shapes:
                io.save_mesh(os.path.join(folder, f"{_file_name(name)}.obj"), V, F)
            rows = amplify(folder, os.path.join(tmp, "out"), variations=self.variations,
                           workers=1, seed=self.seed, coords=self.coords, drop_rejected=True,
                           progress=lambda i, n: progress(i, n, "variations"))
            made = [(by_file[r["source"]], by_file[r["target"]],
                     io.load_mesh(os.path.join(tmp, "out", "variations", r["output"]))[0])
                    for r in rows if r["status"] == "ok"]
        return coll, made, len(rows)

    def apply(self, context, result):
        coll, made, total = result
        out = _new_collection(f"{coll}_variations", context)
        objects = [_copy_with(bpy.data.objects[s], f"{s}__{t}", V, out) for s, t, V in made]
        _select_only(context, objects)
        self.report({"INFO"}, f"cagekit: {len(objects)} of {total} variation(s) accepted, "
                              f"in {out.name}")


def _file_name(name: str) -> str:
    """An object name as a file name (characters other than letters, digits, ``-`` and
    ``_`` become ``_``)."""
    return "".join(c if c.isalnum() or c in "-_" else "_" for c in name)


CLASSES = (CAGEKIT_OT_fit_cage, CAGEKIT_OT_bind, CAGEKIT_OT_unbind,
           CAGEKIT_OT_deform_to_target, CAGEKIT_OT_transfer_pose, CAGEKIT_OT_amplify)
