"""The "cagekit" tab of the 3D view's sidebar (N panel)."""

from __future__ import annotations

import bpy

from . import live


class CagekitSettings(bpy.types.PropertyGroup):
    """What the panel's transfer and amplify buttons take (stored with the scene)."""

    template: bpy.props.PointerProperty(type=bpy.types.Object, name="Template")
    template_cage: bpy.props.PointerProperty(type=bpy.types.Object, name="Template cage")
    poses: bpy.props.PointerProperty(type=bpy.types.Collection, name="Poses")
    character: bpy.props.PointerProperty(type=bpy.types.Object, name="Character")
    collection: bpy.props.PointerProperty(type=bpy.types.Collection, name="Collection")
    variations: bpy.props.IntProperty(name="Variations", default=4, min=1)


def _name(idblock) -> str:
    return idblock.name if idblock is not None else ""


class CAGEKIT_PT_panel(bpy.types.Panel):
    bl_label = "cagekit"
    bl_idname = "CAGEKIT_PT_panel"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "cagekit"

    def draw(self, context):
        layout, s = self.layout, context.scene.cagekit
        obj = context.active_object
        col = layout.column(align=True)
        col.label(text="Cage")
        col.operator("cagekit.fit_cage")
        row = col.row(align=True)
        row.operator("cagekit.bind")
        row.operator("cagekit.unbind")
        if obj is not None and live.is_bound(obj):
            col.label(text=f"{obj.name}: bound to {obj.cagekit_cage.name} "
                           f"({obj[live.COORDS]})", icon="LINKED")
        layout.separator()
        col = layout.column(align=True)
        col.label(text="Fit (select the source, then the target)")
        col.operator("cagekit.deform_to_target")
        layout.separator()
        col = layout.column(align=True)
        col.label(text="Pose transfer (landmarks: vertex groups)")
        for prop in ("template", "template_cage", "poses", "character"):
            col.prop(s, prop)
        op = col.operator("cagekit.transfer_pose")
        op.template, op.template_cage = _name(s.template), _name(s.template_cage)
        op.poses, op.character = _name(s.poses), _name(s.character)
        layout.separator()
        col = layout.column(align=True)
        col.label(text="Variations")
        col.prop(s, "collection")
        col.prop(s, "variations")
        op = col.operator("cagekit.amplify")
        op.collection, op.variations = _name(s.collection), s.variations


CLASSES = (CagekitSettings, CAGEKIT_PT_panel)


def register() -> None:
    bpy.types.Scene.cagekit = bpy.props.PointerProperty(type=CagekitSettings)


def unregister() -> None:
    del bpy.types.Scene.cagekit
