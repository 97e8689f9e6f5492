"""HumV-USD Avatar: write a HumV-USD avatar layer from Blender and import it into the scene;
import a whole composed stage and export the edited scene back as a HumV stage.

The panel (3D Viewport > Sidebar (N) > HumV) holds one person's values, stored on the scene
(``scene.humv_avatar``). "Build Avatar Layer" (operator ``humv.build_avatar_layer``) calls
:func:`humv_usd.avatar.api.author_avatar` — the same code as ``humv-usd avatar`` and
``humv-usd compose`` — to write the ``.usda`` layer, then (option "Import Into Scene")
imports that file with Blender's USD importer so the avatar appears in the viewport.

"Import HumV Stage" (``humv.import_stage``) imports a composed ``OUT/stage.usda`` (scene, people
with their skin and garment materials, cameras) with Blender's USD importer and sets the scene's
frame range and rate from the stage (Blender's importer leaves the rate). "Export HumV Stage"
(``humv.export_stage``) writes the scene with ``wm.usd_export`` (animation included) and adopts
it with :func:`humv_usd.pipeline.adopt.adopt` (``humv-usd adopt --from`` the imported stage):
one folder with a stage HumV renders (see ``humv-usd adopt --help``).

The add-on needs the ``humv_usd`` package importable in Blender's Python: see README.md next to
this folder. Values are checked by HumV-USD's scenario validator (``humv_usd/scenario/spec.py`` is
the one list of ranges); the slider ranges below only mirror it.

No ``from __future__ import annotations`` here: Blender reads the property definitions from the
classes' annotations, which must stay objects, not strings.
"""
import os
import sys

import bpy
from bpy.props import (BoolProperty, EnumProperty, FloatProperty, FloatVectorProperty,
                       PointerProperty, StringProperty)

bl_info = {
    "name": "HumV-USD Avatar",
    "author": "HumV-USD",
    "version": (0, 1, 0),
    "blender": (4, 2, 0),
    "location": "3D Viewport > Sidebar (N) > HumV",
    "description": "Write a HumV-USD avatar layer (USD) for one person and import it",
    "category": "Import-Export",
}

ADDON = __name__

#: Shown when ``import humv_usd`` fails.
IMPORT_HELP = ("cannot import humv_usd ({reason}). Add the HumV-USD repository and the "
               "site-packages of its .venv under Edit > Preferences > Add-ons > HumV-USD Avatar "
               "> Python Paths, or install the package into Blender's Python "
               "(see tools/blender_addon/README.md)")

#: Scenario keys as the validator names them → the panel's labels.
LABEL_OF_KEY = {
    "human[0].id": "Id",
    "human[0].sex": "Sex",
    "human[0].age_yr": "Age",
    "human[0].stature_m": "Stature",
    "human[0].mass_kg": "Mass",
    "human[0].build": "Build",
    "human[0].fitness": "Fitness",
    "human[0].activity": "Activity",
    "placement[0].position_m": "Position",
    "placement[0].heading_deg": "Heading",
    "general.fps": "Frame Rate",
    "general.duration_s": "Duration",
    "out_path": "Output Path",
}

_state = {"import_error": None}


def _prefs():
    addon = bpy.context.preferences.addons.get(ADDON)
    return addon.preferences if addon else None


def _extra_paths() -> list[str]:
    prefs = _prefs()
    text = prefs.python_paths if prefs else ""
    return [bpy.path.abspath(p.strip()) for p in text.split(os.pathsep) if p.strip()]


def humv_api(module="humv_usd.avatar.api"):
    """``humv_usd.avatar.api`` (or ``module``; after adding the preference's paths to sys.path),
    or raise ImportError with the message the user sees."""
    import importlib

    for path in reversed(_extra_paths()):
        if path not in sys.path:
            sys.path.insert(0, path)
    try:
        api = importlib.import_module(module)
    except ImportError as exc:
        message = IMPORT_HELP.format(reason=exc)
        _state["import_error"] = message
        raise ImportError(message) from exc
    _state["import_error"] = None
    return api


def user_message(line: str) -> str:
    """Rename the scenario key that starts a problem line to the panel's label."""
    for key, label in LABEL_OF_KEY.items():
        if line.startswith(key) and line[len(key):len(key) + 1] in (" ", "["):
            return label + line[len(key):]
    return line


def _items(*names):
    return [(n, n, "") for n in names]


class HumvAvatarPreferences(bpy.types.AddonPreferences):
    bl_idname = ADDON

    python_paths: StringProperty(
        name="Python Paths",
        description=("Folders added to Python's sys.path before importing humv_usd, separated "
                     f"by '{os.pathsep}': the HumV-USD repository and its .venv's site-packages"),
        default="")

    def draw(self, context):
        self.layout.prop(self, "python_paths")
        if _state["import_error"]:
            self.layout.label(text=_state["import_error"], icon="ERROR")


class HumvAvatarSettings(bpy.types.PropertyGroup):
    human_id: StringProperty(name="Id", default="p1",
                             description="Id of the person: prim /World/Humans/<id>")
    sex: EnumProperty(name="Sex", items=_items("male", "female"), default="male")
    age_yr: FloatProperty(name="Age [yr]", default=30.0, soft_min=1.0, soft_max=100.0)
    stature_m: FloatProperty(name="Stature [m]", default=1.75, soft_min=0.7, soft_max=2.3,
                             precision=3, step=1, description="Standing height [m]")
    mass_kg: FloatProperty(name="Mass [kg]", default=75.0, soft_min=7.0, soft_max=250.0,
                           description="Body mass [kg]")
    build: EnumProperty(name="Build", items=_items("slim", "average", "muscular"),
                        default="average")
    fitness: EnumProperty(name="Fitness", items=_items("low", "average", "high", "athlete"),
                          default="average")
    activity: EnumProperty(name="Activity",
                           items=_items("stand", "standTurn", "walk", "run", "postExercise"),
                           default="stand")
    position_m: FloatVectorProperty(name="Position [m]", size=3, default=(0.0, 0.0, 0.0),
                                    description="Feet position: x east, y north, z up [m]")
    heading_deg: FloatProperty(name="Heading [deg]", default=0.0, soft_min=-360.0,
                               soft_max=360.0,
                               description="Direction faced, compass azimuth (0 = north, "
                                           "90 = east)")
    fps: FloatProperty(name="Frame Rate [fps]", default=30.0, soft_min=0.01, soft_max=1000.0,
                       description="Frames per second of the layer's time codes")
    duration_s: FloatProperty(name="Duration [s]", default=0.0, soft_min=0.0, soft_max=600.0,
                              description="Length; frames = round(duration * fps) + 1")
    output_path: StringProperty(name="Output", subtype="FILE_PATH",
                                default="//humv_avatar_p1.usda",
                                description="Avatar layer file to write (.usda); '//' is the "
                                            ".blend file's folder")
    import_layer: BoolProperty(name="Import Into Scene", default=True,
                               description="Import the written layer with Blender's USD "
                                           "importer (sets the scene's frame range and rate)")
    stage_path: StringProperty(name="Stage", subtype="FILE_PATH", default="",
                               description="Composed HumV stage (OUT/stage.usda) to import; "
                                           "the export restores what Blender drops from it")
    export_dir: StringProperty(name="Export Folder", subtype="DIR_PATH", default="//humv_export",
                               description="Folder for the adopted HumV stage (stage.usda, "
                                           "layers/adopted.usda, blender_export.usda)")


def resolve_output(path: str) -> str:
    """Absolute output path; '//' paths need a saved .blend file."""
    if path.startswith("//") and not bpy.data.filepath:
        raise ValueError(f"Output Path = {path!r}: '//' is relative to the .blend file, which "
                         "is not saved yet; save it or choose an absolute path")
    return bpy.path.abspath(path)


class HUMV_OT_build_avatar_layer(bpy.types.Operator):
    """Write the avatar layer (USD) of the person set in the HumV panel, then import it"""

    bl_idname = "humv.build_avatar_layer"
    bl_label = "Build Avatar Layer"
    bl_options = {"REGISTER", "UNDO"}

    def _fail(self, lines):
        for line in lines:
            self.report({"ERROR"}, line)
        return {"CANCELLED"}

    def execute(self, context):
        s = context.scene.humv_avatar
        try:
            api = humv_api()
        except ImportError as exc:
            return self._fail([str(exc)])
        try:
            out_path = resolve_output(s.output_path)
        except ValueError as exc:
            return self._fail([str(exc)])
        try:
            written = api.author_avatar(
                out_path, id=s.human_id, sex=s.sex, age_yr=s.age_yr, stature_m=s.stature_m,
                mass_kg=s.mass_kg, build=s.build, fitness=s.fitness, activity=s.activity,
                position_m=tuple(s.position_m), heading_deg=s.heading_deg, fps=s.fps,
                duration_s=s.duration_s)
        except Exception as exc:  # InputError (one line per problem), missing data, I/O
            lines = getattr(exc, "problems", None) or [str(exc) or type(exc).__name__]
            return self._fail([user_message(line) for line in lines])
        if s.import_layer:
            try:
                result = bpy.ops.wm.usd_import(filepath=str(written), set_frame_range=True)
            except RuntimeError as exc:   # the importer's error reports
                result, why = set(), f": {exc}"
            else:
                why = ""
            if "FINISHED" not in result:
                return self._fail([f"wrote {written}, but Blender's USD import failed{why}"])
            set_frame_rate(context.scene, s.fps)  # play at the layer's rate
        self.report({"INFO"}, f"HumV-USD avatar layer written: {written}")
        return {"FINISHED"}


def stage_frame_rate(path: str):
    """timeCodesPerSecond of a USD file's root layer (None when unreadable)."""
    try:
        from pxr import Sdf
        layer = Sdf.Layer.FindOrOpen(path)
    except Exception:  # noqa: BLE001 (no USD Python bindings, or not a USD file)
        return None
    return layer.timeCodesPerSecond if layer and layer.HasTimeCodesPerSecond() else None


def set_frame_rate(scene, fps: float) -> None:
    """Blender plays at fps / fps_base."""
    scene.render.fps = max(1, round(fps))
    scene.render.fps_base = scene.render.fps / fps


class HUMV_OT_import_stage(bpy.types.Operator):
    """Import a composed HumV stage (people, garments, scene, cameras) with its frame rate"""

    bl_idname = "humv.import_stage"
    bl_label = "Import HumV Stage"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        s = context.scene.humv_avatar
        path = bpy.path.abspath(s.stage_path)
        if not os.path.isfile(path):
            self.report({"ERROR"}, f"Stage = {s.stage_path!r}: expected an existing USD file "
                                   "(OUT/stage.usda of humv-usd compose)")
            return {"CANCELLED"}
        try:
            result = bpy.ops.wm.usd_import(filepath=path, set_frame_range=True)
        except RuntimeError as exc:
            self.report({"ERROR"}, f"Blender's USD import failed: {exc}")
            return {"CANCELLED"}
        if "FINISHED" not in result:
            self.report({"ERROR"}, "Blender's USD import failed")
            return {"CANCELLED"}
        fps = stage_frame_rate(path)
        if fps:
            set_frame_rate(context.scene, fps)
        self.report({"INFO"}, f"HumV stage imported: {path}")
        return {"FINISHED"}


class HUMV_OT_export_stage(bpy.types.Operator):
    """Export the scene (USD, with animation) and adopt it as a HumV stage"""

    bl_idname = "humv.export_stage"
    bl_label = "Export HumV Stage"
    bl_options = {"REGISTER"}

    def execute(self, context):
        s = context.scene.humv_avatar
        try:
            adopt = humv_api("humv_usd.pipeline.adopt")
        except ImportError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        try:
            out = resolve_output(s.export_dir)
        except ValueError as exc:
            self.report({"ERROR"}, str(exc).replace("Output Path", "Export Folder"))
            return {"CANCELLED"}
        original = bpy.path.abspath(s.stage_path) if s.stage_path else None
        os.makedirs(out, exist_ok=True)
        export = os.path.join(out, "blender_export.usda")
        bpy.ops.wm.usd_export(filepath=export, export_animation=True)
        try:
            stage, _ = adopt.adopt(export, out, original if original and os.path.isfile(original) else None)
        except Exception as exc:  # InputError (one line per problem)
            for line in getattr(exc, "problems", None) or [str(exc) or type(exc).__name__]:
                self.report({"ERROR"}, line)
            return {"CANCELLED"}
        self.report({"INFO"}, f"HumV stage written: {stage}")
        return {"FINISHED"}


class HUMV_PT_avatar(bpy.types.Panel):
    bl_label = "HumV-USD Avatar"
    bl_idname = "HUMV_PT_avatar"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "HumV"

    def draw(self, context):
        layout = self.layout
        s = context.scene.humv_avatar
        if _state["import_error"]:
            box = layout.box()
            box.alert = True
            box.label(text="humv_usd is not importable", icon="ERROR")
            box.label(text="Set Python Paths in the add-on's preferences")
        col = layout.column(align=False)
        col.use_property_split = True
        col.use_property_decorate = False
        for name in ("human_id", "sex", "age_yr", "stature_m", "mass_kg", "build", "fitness",
                     "activity", "position_m", "heading_deg", "fps", "duration_s"):
            col.prop(s, name)
        layout.prop(s, "output_path")
        layout.prop(s, "import_layer")
        layout.operator(HUMV_OT_build_avatar_layer.bl_idname, icon="ARMATURE_DATA")
        layout.separator()
        layout.prop(s, "stage_path")
        layout.operator(HUMV_OT_import_stage.bl_idname, icon="IMPORT")
        layout.prop(s, "export_dir")
        layout.operator(HUMV_OT_export_stage.bl_idname, icon="EXPORT")


CLASSES = (HumvAvatarPreferences, HumvAvatarSettings, HUMV_OT_build_avatar_layer,
           HUMV_OT_import_stage, HUMV_OT_export_stage, HUMV_PT_avatar)


def register():
    for cls in CLASSES:
        bpy.utils.register_class(cls)
    bpy.types.Scene.humv_avatar = PointerProperty(type=HumvAvatarSettings)


def unregister():
    del bpy.types.Scene.humv_avatar
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
