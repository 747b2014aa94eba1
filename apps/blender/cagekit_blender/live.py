"""Meshes bound to cages: what is stored in the .blend file and the live update.

A bound mesh object keeps, in its own custom properties, the cage object (a pointer, so
renaming either keeps the link), the coordinates' name and the rest state: its vertices
as stored, its world matrix and the cage's world-space vertices at bind time. The
coordinates themselves (an n x k matrix, 40 MB for 50,000 vertices and a 100-vertex
cage) are not saved: they are recomputed from the rest state, identically, the first
time the mesh is needed after opening the file (a second or two for 200,000 vertices).

After every depsgraph update (a cage moved in object or edit mode, an undo), each bound
mesh whose cage vertices changed is written anew: ``binding.deform(cage)`` in world space,
mapped into the mesh's own space. A bound mesh in edit mode is left alone (its edits
would overwrite ours).
"""

from __future__ import annotations

import uuid
from dataclasses import dataclass

import bpy
import numpy as np
from bpy.app.handlers import persistent

from . import meshes

#: custom property names on the bound object
REST = "cagekit_rest"
REST_MATRIX = "cagekit_rest_matrix"
REST_CAGE = "cagekit_rest_cage"
COORDS = "cagekit_coords"
#: a fresh token per bind: tells a cached binding from a stale one (an object deleted and
#: another given its name, a rebind)
TOKEN = "cagekit_bind_id"
KEYS = (REST, REST_MATRIX, REST_CAGE, COORDS, TOKEN)



@dataclass
class _Bound:
    """What is kept in memory for a bound object: the :func:`_key` it was computed for, the
    cagekit binding, and the cage last written from ((k, 3) world, None: write again)."""

    key: tuple
    binding: object
    last: np.ndarray | None


#: object name -> its binding in memory
_runtime: dict[str, _Bound] = {}


def is_bound(obj) -> bool:
    return obj is not None and obj.type == "MESH" and REST in obj and obj.cagekit_cage


def _array(prop, columns: int | None = 3) -> np.ndarray:
    out = np.array(prop, dtype=np.float64)
    return out.reshape(-1, columns) if columns else out


def rest_state(obj):
    """``(rest world vertices (n, 3), rest cage (k, 3), coords)`` stored on ``obj``."""
    M = _array(obj[REST_MATRIX], 4)
    return (meshes.to_world(_array(obj[REST]), M), _array(obj[REST_CAGE]),
            str(obj[COORDS]))


def bind_object(obj, cage, coords: str, binding) -> None:
    """Record ``binding`` (of ``obj``'s world vertices to ``cage``'s) on ``obj``."""
    obj[REST] = meshes.local_vertices(obj).ravel()
    obj[REST_MATRIX] = meshes.matrix(obj).ravel()
    obj[REST_CAGE] = binding.cage_v.ravel()
    obj[COORDS] = coords
    obj[TOKEN] = uuid.uuid4().hex
    obj.cagekit_cage = cage
    _runtime[obj.name] = _Bound(_key(obj), binding, binding.cage_v.copy())


def unbind_object(obj) -> None:
    """Give ``obj`` back its rest vertices and forget its binding."""
    rest = _array(obj[REST])
    if len(rest) == len(obj.data.vertices):
        meshes.set_local_vertices(obj, rest)
    forget(obj)


def forget(obj) -> None:
    """Drop ``obj``'s binding (its stored properties and what is in memory) as it is; a copy
    of a bound object starts with none."""
    for name in KEYS:
        if name in obj:
            del obj[name]
    obj.cagekit_cage = None
    _runtime.pop(obj.name, None)


def _key(obj) -> tuple:
    """Tells whether a cached binding still belongs to the object's stored rest state."""
    return obj.cagekit_cage.name, str(obj.get(TOKEN, ""))


def binding_of(obj):
    """The cagekit binding of a bound object (recomputed from its rest state when the
    file was just opened, the object renamed or its rest changed)."""
    from cagekit.coords import bind

    entry = _runtime.get(obj.name)
    if entry is None or entry.key != _key(obj):
        V, C, coords = rest_state(obj)
        binding = bind(V, C, meshes.triangles(obj.cagekit_cage), method=coords, check=False)
        entry = _runtime[obj.name] = _Bound(_key(obj), binding, C.copy())
    return entry.binding


def update(obj) -> bool:
    """Move a bound object with its cage when the cage changed; True when it was moved."""
    cage = obj.cagekit_cage
    if obj.mode == "EDIT" or cage.type != "MESH":
        return False
    binding = binding_of(obj)
    C = meshes.world_vertices(cage)
    entry = _runtime[obj.name]
    if C.shape != binding.cage_v.shape:  # the cage's topology was edited: keep the mesh
        return False
    if entry.last is not None and np.array_equal(C, entry.last):
        return False
    meshes.set_world_vertices(obj, binding.deform(C))
    entry.last = C
    return True


def update_all() -> int:
    """:func:`update` every bound object; the number moved."""
    moved, bound = 0, [obj for obj in bpy.data.objects if is_bound(obj)]
    for name in set(_runtime) - {obj.name for obj in bound}:  # deleted or unbound
        del _runtime[name]
    for obj in bound:
        try:
            moved += update(obj)
        except Exception as exc:  # noqa: BLE001 - a handler must never raise
            print(f"cagekit: {obj.name}: {' '.join(str(exc).split())}")
    return moved


@persistent
def on_depsgraph_update(scene, depsgraph=None) -> None:
    update_all()


@persistent
def on_undo(scene, *args) -> None:
    # the objects' world matrices are evaluated only by the next depsgraph update: the
    # meshes are rewritten then (the restored data already agrees with the cage)
    for entry in _runtime.values():
        entry.last = None


@persistent
def on_load(*args) -> None:
    _runtime.clear()  # another file: bindings are recomputed when first needed


HANDLERS = (("depsgraph_update_post", on_depsgraph_update), ("undo_post", on_undo),
            ("redo_post", on_undo), ("load_post", on_load))


def register() -> None:
    bpy.types.Object.cagekit_cage = bpy.props.PointerProperty(
        type=bpy.types.Object, name="cagekit cage",
        description="The cage this mesh is bound to (cagekit)")
    for name, fn in HANDLERS:
        getattr(bpy.app.handlers, name).append(fn)


def unregister() -> None:
    for name, fn in HANDLERS:
        handlers = getattr(bpy.app.handlers, name)
        if fn in handlers:
            handlers.remove(fn)
    del bpy.types.Object.cagekit_cage
    _runtime.clear()
