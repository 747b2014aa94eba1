"""cagekit in Blender: automatic cages, live cage deformation, fitting to a target, pose
transfer and variations, all computed by the cagekit library (no second implementation).

Operators ``bpy.ops.cagekit.*`` (:mod:`.operators`), the sidebar tab "cagekit"
(:mod:`.panel`), bound meshes and their live update (:mod:`.live`). See the README's
"Blender" section and docs/blender.md.
"""

from __future__ import annotations

import bpy

from . import live, operators, panel

_CLASSES = operators.CLASSES + panel.CLASSES


def register() -> None:
    for cls in _CLASSES:
        bpy.utils.register_class(cls)
    panel.register()
    live.register()


def unregister() -> None:
    live.unregister()
    panel.unregister()
    for cls in reversed(_CLASSES):
        bpy.utils.unregister_class(cls)
