"""Adopt a Blender USD export (``wm.usd_export``) as a HumV stage layer.

Blender 4.2-5.0 writes a stage a HumV render cannot use as it is:

- everything under one root prim ``/root`` (the ``root_prim_path`` option), each object as an
  Xform with its data (Mesh, Camera, Skeleton) as a child named after the data
  (``/root/World/Scene/warehouse/warehouse``); objects at the top of the outliner sit directly
  under ``/root``;
- materials under ``/root/_materials``, without HumvMaterialAPI;
- attribute names without namespaces (``primvars:humv_thermal_temperature``);
- no applied HumV schemas or HumV attributes on prims (cameras lose HumvSensorAPI, the person's
  SkelRoot HumvAvatarAPI, labels and keypoints; the environment and atmosphere become empty
  Xforms);
- the scene's frame rate (24 unless set), with time codes still in frames.

:func:`adopt_blender_export` maps these back, in this order:

1. **Namespace**: ``/root/World/...`` -> ``/World/...``, ``/root/_materials/<m>`` ->
   ``/World/Materials/<m>``, other objects under ``/root`` -> ``/World/Scene/<name>``; an
   object Xform and its one data prim merge into one prim named like the original prim (the
   data's name when the object's is the data's plus Blender's ``_001`` suffix), with the
   object's transform; relationship targets and connections follow the new paths. Exports
   with ``root_prim_path=""`` (World and ``_materials`` at the top) or ``"/World"`` map the
   same way.
2. **Primvar names**: ``primvars:humv_thermal_temperature`` -> ``primvars:humv:thermal:temperature``
   (every HumV primvar: :data:`HUMV_PRIMVARS`).
3. **From the original stage** (``original``, e.g. ``OUT/stage.usda``; optional): the prims
   Blender cannot carry are copied whole (``/World/Environment``, ``/World/Atmosphere``); every
   adopted prim whose path exists there gets back its HumV API schemas, ``humv:*`` attributes,
   primvars and ``humv:*`` customData (per-face and per-vertex data only while the mesh keeps
   its face and point counts; else Blender's values stay and a warning says so); cameras get
   back their filmback (the sensor's pixel grid; Blender's own depends on its render size);
   materials the export lacks are copied; the root layer's HumV customLayerData and the frame
   rate come from it. An export without time samples (``export_animation=False``) of an
   original that moves is adopted as it is, with a warning (people and garments stay put).
4. **Materials**: a material without HumvMaterialAPI takes it from the original stage's
   material of the same name, else from the library (:data:`humv_usd.catalog.materials.LIBRARY`)
   by name (Blender's ``.001`` suffix ignored); any other material is an InputError.
5. **New meshes** (no temperatures): a held temperature (``fixed``): the object's Blender custom
   property ``humv_temperature_k``, else ``temperature_k``, else the stage's air temperature at
   frame 0; meshes without an instance id get the next free id and the class of their custom
   property ``humv_class`` (else ``label_class``, default ``other``).
"""

from __future__ import annotations

import logging
import re
from dataclasses import dataclass, field

import numpy as np
from pxr import Sdf, Usd, UsdGeom, UsdShade

from humv_usd.catalog.materials import LIBRARY
from humv_usd.errors import InputError, bad_value
from humv_usd.usd import schemas as S
from humv_usd.usd.avatar import BODY_REGION_PRIMVAR, JOS3_SEGMENT_PRIMVAR
from humv_usd.usd.environment import read_weather
from humv_usd.usd.labels import instance_id
from humv_usd.usd.layers import SCOPES, WORLD, set_layer_metadata
from humv_usd.usd.materials import write_material_properties
from humv_usd.usd.mesh import label
from humv_usd.usd.thermal import check_temperatures, has_face_temperatures, write_surface_temperature

log = logging.getLogger(__name__)

#: Blender's default root prim (``wm.usd_export(root_prim_path=...)``) and materials scope
BLENDER_ROOT = "root"
BLENDER_MATERIALS = "_materials"
#: Blender's custom attributes naming the object and its data (``author_blender_name``)
BLENDER_OBJECT_NAME = "userProperties:blender:object_name"
BLENDER_DATA_NAME = "userProperties:blender:data_name"
#: Blender custom properties (object or data) that adopt reads for new meshes
CUSTOM_CLASS = "userProperties:humv_class"
CUSTOM_TEMPERATURE = "userProperties:humv_temperature_k"
#: prim types Blender writes as an object's data child
DATA_TYPES = {"Mesh", "Camera", "Skeleton", "Points", "BasisCurves", "NurbsCurves", "Volume"}
#: HumV primvars, whose namespaces Blender flattens to underscores
HUMV_PRIMVARS = (S.TEMPERATURE_PRIMVAR, S.AIR_GAP_PRIMVAR, BODY_REGION_PRIMVAR, JOS3_SEGMENT_PRIMVAR)
BLENDER_PRIMVAR_NAMES = {
    "primvars:" + n.removeprefix("primvars:").replace(":", "_"): n for n in HUMV_PRIMVARS
}
#: subtrees that hold no geometry: copied whole from the original stage
CARRIED_SCOPES = (SCOPES["environment"], SCOPES["atmosphere"])
#: camera attributes that come from the original sensor (the pixel grid is HumvSensorAPI's)
FILMBACK = ("horizontalAperture", "verticalAperture", "horizontalApertureOffset", "verticalApertureOffset")
_SUFFIX = re.compile(r"^(?P<base>.+?)[._](?P<n>\d{3})$")


@dataclass
class AdoptReport:
    """What :func:`adopt_blender_export` did (for the command's summary and tests)."""

    prims: int = 0
    restored: list[str] = field(default_factory=list)  # prims that got HumV data back
    materials: dict[str, str] = field(default_factory=dict)  # material -> "original" | "library"
    new_meshes: dict[str, dict] = field(default_factory=dict)  # path -> id, class, temperature
    kept_blender_values: list[str] = field(default_factory=list)  # topology changed
    fps: float | None = None
    fps_source: str = ""
    static_export: bool = False  # no time samples in the export, though the original moves


def _base_name(name: str) -> str:
    """A Blender name without its uniqueness suffix (``atom1024_lwir_001`` -> ``atom1024_lwir``)."""
    m = _SUFFIX.match(name)
    return m["base"] if m else name


# ------------------------------------------------------------------------------ namespace
def _data_child(spec: Sdf.PrimSpec) -> Sdf.PrimSpec | None:
    """The data prim of a Blender object Xform (its child with ``blender:data_name``, or its one
    child of a data type named like the object), None when ``spec`` is not such an object."""
    if spec.typeName != "Xform":
        return None
    children = list(spec.nameChildren)
    named = [c for c in children if BLENDER_DATA_NAME in c.properties]
    if len(named) == 1:
        return named[0]
    typed = [c for c in children if c.typeName in DATA_TYPES]
    if len(typed) == 1 and _base_name(spec.name) in (typed[0].name, _base_name(typed[0].name)):
        return typed[0]
    return None


def _merged_name(obj: Sdf.PrimSpec, data: Sdf.PrimSpec) -> str:
    """The object's name, or the data's when the object's is the data's plus a suffix (Blender
    made the object name unique; the data name is the original prim's)."""
    return data.name if _base_name(obj.name) == _base_name(data.name) else obj.name


def _targets(children: list, parent: Sdf.Path, original: frozenset | None) -> dict:
    """{child spec path: its target path under ``parent``}, Blender's renames undone where the
    ``original`` stage's prim paths tell (issue 26):

    * Blender keeps object and data names unique over the whole file, so a second person's
      ``Body`` comes back as ``Body_001``: a suffixed name becomes its base name again when the
      original has that prim at that place (and not the suffixed one) and no sibling takes it;
    * Blender's importer merges an Xform that has one child into that child's object, so
      ``/World/Scene/Ground`` (a scene with no other object) comes back as ``/World/Ground``: a
      prim the original lacks goes one level down when the original has it there under the
      only child of ``parent`` that the export lacks."""
    names = {}
    for c in children:
        data = _data_child(c)
        names[c.path] = _merged_name(c, data) if data is not None else c.name
    targets = {k: parent.AppendChild(v) for k, v in names.items()}
    if not original:
        return targets
    taken = set(names.values())
    for c in children:
        name = names[c.path]
        base = _base_name(name)
        if (
            base != name
            and base not in taken
            and parent.AppendChild(name) not in original
            and parent.AppendChild(base) in original
        ):
            names[c.path] = base
            taken.add(base)
            targets[c.path] = parent.AppendChild(base)
    for c in children:
        here = targets[c.path]
        if here in original:
            continue
        below = [
            p
            for p in original
            if p.GetParentPath().GetParentPath() == parent
            and p.name == here.name
            and p.GetParentPath().name not in taken
        ]
        if len(below) == 1:
            targets[c.path] = below[0]
    return targets


def _plan(
    src: Sdf.Layer, root: Sdf.PrimSpec | None, tops: list, original: frozenset | None = None
) -> tuple[list[tuple[Sdf.Path, list[Sdf.PrimSpec]]], dict]:
    """[(target path, [source prim specs merged into it])], {source path: target path}.
    ``original``: the prim paths of the original stage (Blender's renames undone)."""
    plan: list[tuple[Sdf.Path, list[Sdf.PrimSpec]]] = []
    paths: dict[Sdf.Path, Sdf.Path] = {} if root is None else {root.path: WORLD}

    def visit(spec: Sdf.PrimSpec, target: Sdf.Path) -> None:
        data = _data_child(spec)
        sources = [spec] if data is None else [spec, data]
        plan.append((target, sources))
        for s in sources:
            paths[s.path] = target
        children = [
            child for s in sources for child in s.nameChildren if data is None or child.path != data.path
        ]
        targets = _targets(children, target, original)
        for child in children:
            visit(child, targets[child.path])

    scene_objects = [c for c in tops if c.name not in (WORLD.name, BLENDER_MATERIALS)]
    scene_targets = _targets(scene_objects, SCOPES["scene"], original)
    for child in tops:
        if child.name in (WORLD.name, BLENDER_MATERIALS):
            target = WORLD if child.name == WORLD.name else SCOPES["materials"]
            paths[child.path] = target
            plan.append((target, [child]))
            grands = list(child.nameChildren)
            targets = _targets(grands, target, original)
            for grand in grands:
                visit(grand, targets[grand.path])
        else:  # a top-level Blender object: a scene object
            visit(child, scene_targets[child.path])
    return plan, paths


def _define_parents(dst: Sdf.Layer, original: Usd.Stage | None) -> None:
    """A prim the plan put under a parent the export lacks (the scene scope Blender merged
    away, a top-level object's /World/Scene) would sit under an ``over`` and not exist: define
    such parents, with the original's type (else Xform)."""
    overs = []

    def visit(path: Sdf.Path) -> None:
        spec = dst.GetPrimAtPath(path) if path.IsPrimPath() else None
        if spec is not None and spec.specifier == Sdf.SpecifierOver:
            overs.append(spec)

    dst.Traverse(Sdf.Path.absoluteRootPath, visit)

    def holds_a_def(spec: Sdf.PrimSpec) -> bool:
        return any(c.specifier == Sdf.SpecifierDef or holds_a_def(c) for c in spec.nameChildren)

    for spec in overs:
        if not holds_a_def(spec):
            continue
        spec.specifier = Sdf.SpecifierDef
        prim = original.GetPrimAtPath(spec.path) if original is not None else None
        spec.typeName = (prim.GetTypeName() if prim else "") or "Xform"


def _map_path(path: Sdf.Path, paths: dict) -> Sdf.Path:
    prim = path.GetPrimPath()
    probe = prim
    while probe != Sdf.Path.absoluteRootPath and probe not in paths:
        probe = probe.GetParentPath()
    if probe not in paths:
        return path
    return path.ReplacePrefix(probe, paths[probe])


def _copy_prim(src: Sdf.Layer, dst: Sdf.Layer, target: Sdf.Path, sources: list[Sdf.PrimSpec]) -> None:
    """Define ``target`` with the type, metadata and properties of ``sources`` (object, then
    data: the data wins; its xform ops are renamed so the object's transform comes first)."""
    spec = Sdf.CreatePrimInLayer(dst, target)
    spec.specifier = Sdf.SpecifierDef
    data = sources[-1]
    spec.typeName = data.typeName or sources[0].typeName
    for s in sources:
        for key in s.ListInfoKeys():
            if key not in ("specifier", "typeName"):
                spec.SetInfo(key, s.GetInfo(key))
    order: list[str] = []
    for k, s in enumerate(sources):
        rename = {}
        ops = list(s.properties["xformOpOrder"].default or []) if "xformOpOrder" in s.properties else []
        if k and ops:  # the data's own ops after the object's, under a suffix
            rename = {op: f"{op}:data" for op in ops}
        order.extend(rename.get(op, op) for op in ops)
        for prop in s.properties:
            if prop.name == "xformOpOrder":
                continue
            name = rename.get(prop.name, prop.name)
            Sdf.CopySpec(src, prop.path, dst, target.AppendProperty(name))
    if order:
        attr = Sdf.AttributeSpec(spec, "xformOpOrder", Sdf.ValueTypeNames.TokenArray, Sdf.VariabilityUniform)
        attr.default = order


def _remap_targets(dst: Sdf.Layer, paths: dict) -> None:
    """Relationship targets and attribute connections follow the prims to their new paths."""

    def fix(path: Sdf.Path) -> None:
        spec = dst.GetObjectAtPath(path)
        if isinstance(spec, Sdf.RelationshipSpec):
            spec.targetPathList.ModifyItemEdits(lambda p: _map_path(p, paths))
        elif isinstance(spec, Sdf.AttributeSpec):
            spec.connectionPathList.ModifyItemEdits(lambda p: _map_path(p, paths))

    dst.Traverse(Sdf.Path.absoluteRootPath, fix)


def _rename_primvars(dst: Sdf.Layer) -> None:
    def fix(path: Sdf.Path) -> None:
        if not path.IsPropertyPath() or path.name not in BLENDER_PRIMVAR_NAMES:
            return
        owner = dst.GetPrimAtPath(path.GetPrimPath())
        ours = path.GetPrimPath().AppendProperty(BLENDER_PRIMVAR_NAMES[path.name])
        if ours.name not in owner.properties:
            Sdf.CopySpec(dst, path, dst, ours)
        renamed.append((owner, path.name))

    renamed: list = []
    dst.Traverse(Sdf.Path.absoluteRootPath, fix)
    for owner, name in renamed:
        owner.RemoveProperty(owner.properties[name])


def _blender_root(src: Sdf.Layer) -> tuple[Sdf.PrimSpec | None, list]:
    """(Blender's root prim, the prims under it); with ``root_prim_path=""`` there is no root
    prim: (None, the layer's root prims). A root named World (``root_prim_path="/World"``) is
    Blender's when it holds the exported World or ``_materials``."""
    name = src.defaultPrim or BLENDER_ROOT
    root = src.GetPrimAtPath(Sdf.Path.absoluteRootPath.AppendChild(name))
    if root is None and name != BLENDER_ROOT:
        root = src.GetPrimAtPath(Sdf.Path.absoluteRootPath.AppendChild(BLENDER_ROOT))
    if root is not None and (
        root.name != WORLD.name or WORLD.name in root.nameChildren or BLENDER_MATERIALS in root.nameChildren
    ):
        return root, list(root.nameChildren)
    return None, list(src.rootPrims)


def convert_namespace(src: Sdf.Layer, original: Usd.Stage | None = None) -> tuple[Sdf.Layer, int]:
    """Steps 1-2 of the module doc: a new layer with Blender's prims at HumV paths and HumV
    primvar names, and the number of prims. With the ``original`` stage, names Blender made
    unique with a suffix (``Body_001``) or merged into a parent go back to the original's
    (:func:`_targets`)."""
    root, tops = _blender_root(src)
    if not tops:
        raise InputError(bad_value("BLENDER_EXPORT", src.identifier, "expected prims (a Blender USD export)"))
    dst = Sdf.Layer.CreateAnonymous("adopted.usda")
    known = None
    if original is not None:
        known = frozenset(p.GetPath() for p in original.Traverse(Usd.TraverseInstanceProxies()))
    plan, paths = _plan(src, root, tops, known)
    for target, sources in plan:
        _copy_prim(src, dst, target, sources)
    _define_parents(dst, original)
    _remap_targets(dst, paths)
    _rename_primvars(dst)
    dst.defaultPrim = WORLD.name
    return dst, len(plan)


# ------------------------------------------------------------------------------ the original
def _is_humv_property(name: str) -> bool:
    return name.startswith(("humv:", "primvars:humv:"))


def _counts(spec: Sdf.PrimSpec) -> tuple[int | None, int | None]:
    """(faces, points) of a mesh spec (None when not authored)."""

    def length(name):
        prop = spec.properties.get(name) if spec else None
        value = prop.default if prop is not None else None
        if value is None and prop is not None:  # time-sampled only
            layer = spec.layer
            times = layer.ListTimeSamplesForPath(prop.path)
            value = layer.QueryTimeSample(prop.path, times[0]) if times else None
        return None if value is None else len(value)

    return length("faceVertexCounts"), length("points")


def _restore_prim(orig: Sdf.Layer, dst: Sdf.Layer, path: Sdf.Path, report: AdoptReport) -> None:
    """HumV schemas, attributes and customData of the original prim ``path`` onto the adopted
    prim (per-face / per-vertex primvars only while the topology is the original's)."""
    o, d = orig.GetPrimAtPath(path), dst.GetPrimAtPath(path)
    humv = [p for p in o.properties if _is_humv_property(p.name)]
    schemas = [x for x in o.GetInfo("apiSchemas").GetAddedOrExplicitItems() if x.startswith("Humv")]
    custom = {k: v for k, v in dict(o.customData).items() if k.startswith("humv:")}
    if not (humv or schemas or custom):
        return
    same_topology = o.typeName != "Mesh" or _counts(o) == _counts(d)
    for prop in humv:
        if prop.name.startswith("primvars:") and not same_topology:
            continue
        Sdf.CopySpec(orig, prop.path, dst, prop.path)
    if not same_topology and any(p.name.startswith("primvars:") for p in humv):
        report.kept_blender_values.append(str(path))
        log.warning("%s: faces or points differ from the original; Blender's per-face values kept", path)
    if schemas:
        have = list(d.GetInfo("apiSchemas").GetAddedOrExplicitItems()) if d.HasInfo("apiSchemas") else []
        d.SetInfo(
            "apiSchemas", Sdf.TokenListOp.Create(prependedItems=have + [x for x in schemas if x not in have])
        )
    for key, value in custom.items():
        d.SetInfoDictionaryValue("customData", key, value)
    if o.typeName == "Camera":  # the sensor's pixel grid, not Blender's render size
        for name in FILMBACK:
            if name in o.properties:
                Sdf.CopySpec(orig, o.properties[name].path, dst, o.properties[name].path)
    report.restored.append(str(path))


def restore_from_original(dst: Sdf.Layer, original: Usd.Stage, report: AdoptReport) -> None:
    """Step 3 of the module doc."""
    orig = original.Flatten()
    for scope in CARRIED_SCOPES:
        if orig.GetPrimAtPath(scope) is None:
            continue
        if dst.GetPrimAtPath(scope) is not None:
            del dst.GetPrimAtPath(scope.GetParentPath()).nameChildren[scope.name]
        Sdf.CreatePrimInLayer(dst, scope)
        Sdf.CopySpec(orig, scope, dst, scope)
    carried = tuple(CARRIED_SCOPES)
    paths: list[Sdf.Path] = []
    dst.Traverse(WORLD, lambda p: paths.append(p) if p.IsPrimPath() else None)
    for path in paths:
        if any(path.HasPrefix(c) for c in carried) or orig.GetPrimAtPath(path) is None:
            continue
        _restore_prim(orig, dst, path, report)
    materials = orig.GetPrimAtPath(SCOPES["materials"])
    for mat in materials.nameChildren if materials else []:
        if dst.GetPrimAtPath(mat.path) is None:  # e.g. the ground's substrate
            Sdf.CreatePrimInLayer(dst, mat.path)
            Sdf.CopySpec(orig, mat.path, dst, mat.path)


# ------------------------------------------------------------------------------ materials, new meshes
def adopt_materials(stage: Usd.Stage, original: Usd.Stage | None, report: AdoptReport) -> None:
    """Step 4: every material under /World/Materials carries HumvMaterialAPI."""
    scope = stage.GetPrimAtPath(SCOPES["materials"])
    for prim in scope.GetChildren() if scope else []:
        if not prim.IsA(UsdShade.Material) or prim.HasAPI(S.MATERIAL_API):
            if prim.HasAPI(S.MATERIAL_API):
                report.materials.setdefault(prim.GetName(), "original")
            continue
        name = _base_name(prim.GetName())
        source = original.GetPrimAtPath(SCOPES["materials"].AppendChild(name)) if original else None
        if source and source.HasAPI(S.MATERIAL_API):
            prim.ApplyAPI(S.MATERIAL_API)
            for attr in source.GetAttributes():
                if _is_humv_property(attr.GetName()) and attr.HasAuthoredValue():
                    prim.CreateAttribute(attr.GetName(), attr.GetTypeName(), custom=False).Set(attr.Get())
            report.materials[prim.GetName()] = "original"
        elif name in LIBRARY:
            write_material_properties(prim, LIBRARY[name])
            report.materials[prim.GetName()] = "library"
        else:
            raise InputError(
                bad_value(
                    str(prim.GetPath()),
                    prim.GetName(),
                    "expected the name of a library material (Blender's .001 suffix is ignored): "
                    + ", ".join(sorted(LIBRARY)),
                )
            )


def _custom(prim: Usd.Prim, name: str):
    """A Blender custom property on the mesh or its parents up to /World (None when absent)."""
    p = prim
    while p and p.GetPath() != WORLD:
        attr = p.GetAttribute(name)
        if attr and attr.HasAuthoredValue():
            return attr.Get()
        p = p.GetParent()
    return None


def _air_temperature(stage: Usd.Stage) -> float | None:
    try:
        return float(read_weather(stage, [stage.GetStartTimeCode()]).air_temperature_k[0])
    except InputError:
        return None


def _rendered_meshes(stage: Usd.Stage) -> list[Usd.Prim]:
    return [
        p
        for p in stage.Traverse()
        if p.IsA(UsdGeom.Mesh)
        and not any(p.GetPath().HasPrefix(c) for c in CARRIED_SCOPES)
        and UsdGeom.Imageable(p).ComputePurpose() in (UsdGeom.Tokens.default_, UsdGeom.Tokens.render)
    ]


def label_classes() -> list[str]:
    """The class tokens HumvLabelAPI allows (from the registered schema)."""
    definition = Usd.SchemaRegistry().FindAppliedAPIPrimDefinition(S.LABEL_API)
    return list(definition.GetSchemaAttributeSpec(S.LABEL_CLASS).allowedTokens)


def _check_class(value, where: str) -> str:
    allowed = label_classes()
    if str(value) not in allowed:
        raise InputError(bad_value(where, value, "expected one of " + ", ".join(allowed)))
    return str(value)


def adopt_new_meshes(
    stage: Usd.Stage, report: AdoptReport, temperature_k: float | None = None, label_class: str = "other"
) -> None:
    """Step 5: meshes without temperatures get a held one, meshes without an id a new label."""
    _check_class(label_class, "--label-class")
    meshes = _rendered_meshes(stage)
    used = [instance_id(p) for p in stage.Traverse()]
    next_id = max(used, default=0) + 1
    air = None
    for prim in meshes:
        entry: dict = {}
        if not has_face_temperatures(prim):
            value = _custom(prim, CUSTOM_TEMPERATURE)
            if value is not None and (isinstance(value, bool) or not isinstance(value, (int, float))):
                raise InputError(  # e.g. a string property: float() ended in a traceback
                    bad_value(f"{prim.GetPath()}.{CUSTOM_TEMPERATURE}", value, "expected a number [K]")
                )
            if value is None:
                value = temperature_k
            if value is None:
                air = _air_temperature(stage) if air is None else air
                value = air
            if value is not None:
                check_temperatures([value], f"{prim.GetPath()}: temperature")
            else:
                raise InputError(
                    bad_value(
                        f"{prim.GetPath()}.{S.TEMPERATURE_PRIMVAR}",
                        None,
                        "expected temperatures: give --temperature-k, a custom property "
                        "humv_temperature_k in Blender, or --from a stage with an environment",
                    )
                )
            faces = len(UsdGeom.Mesh(prim).GetFaceVertexCountsAttr().Get() or [])
            write_surface_temperature(prim, "fixed", np.full(faces, float(value)))
            entry["temperature_k"] = float(value)
        if instance_id(prim) == 0:
            custom = _custom(prim, CUSTOM_CLASS)
            cls = label_class if custom is None else _check_class(custom, f"{prim.GetPath()}.{CUSTOM_CLASS}")
            label(prim, next_id, cls)
            entry.update(instance_id=next_id, label_class=cls)
            next_id += 1
        if entry:
            report.new_meshes[str(prim.GetPath())] = entry


# ------------------------------------------------------------------------------ all steps
def without_temperatures(layer: Sdf.Layer, prims=None) -> Sdf.Layer:
    """A copy of ``layer`` without per-face temperature primvars (on the prims at ``prims``
    only, when given): the thermal tool's output, stale once geometry moved (issue 27)."""
    out = Sdf.Layer.CreateAnonymous(".usda")
    out.TransferContent(layer)
    wanted = None if prims is None else {Sdf.Path(str(p)) for p in prims}
    found = []

    def visit(path: Sdf.Path) -> None:
        if path.IsPropertyPath() and path.name == S.TEMPERATURE_PRIMVAR:
            if wanted is None or path.GetPrimPath() in wanted:
                found.append(path)

    out.Traverse(Sdf.Path.absoluteRootPath, visit)
    for path in found:
        out.GetPrimAtPath(path.GetPrimPath()).RemoveProperty(out.GetPropertyAtPath(path))
    return out


def adopt_blender_export(
    export: Sdf.Layer,
    original: Usd.Stage | None = None,
    *,
    fps: float | None = None,
    temperature_k: float | None = None,
    label_class: str = "other",
) -> tuple[Sdf.Layer, AdoptReport]:
    """The Blender export ``export`` (a flattened layer) as one HumV layer (module doc) and what
    was done. ``original``: the composed stage the export came from (restores what Blender
    drops); ``fps``: frames per second (default: the original's, else the export's);
    ``temperature_k``, ``label_class``: for new meshes."""
    report = AdoptReport()
    layer, report.prims = convert_namespace(export, original)
    if original is not None:
        restore_from_original(layer, original, report)
    if fps is not None:
        report.fps, report.fps_source = float(fps), "--fps"
    elif original is not None:
        report.fps, report.fps_source = float(original.GetTimeCodesPerSecond()), "the original stage"
    else:
        report.fps, report.fps_source = float(export.timeCodesPerSecond), "the Blender export"
        log.warning("frame rate %g from the Blender export (give --fps or --from)", report.fps)
    start = export.startTimeCode if export.HasStartTimeCode() else 0
    end = export.endTimeCode if export.HasEndTimeCode() else start
    if original is not None:
        start, end = original.GetStartTimeCode(), original.GetEndTimeCode()
        if end > start and not export.ListAllTimeSamples():
            report.static_export = True
            log.warning(
                "the Blender export has no animation (wm.usd_export(export_animation=False)): "
                "people and garments stay at the exported frame; export with Animation on"
            )
    set_layer_metadata(
        layer, report.fps, int(end - start) + 1, "HumV-USD layer adopted from a Blender export"
    )
    layer.startTimeCode, layer.endTimeCode = start, end
    stage = Usd.Stage.Open(layer)
    adopt_materials(stage, original, report)
    adopt_new_meshes(stage, report, temperature_k, label_class)
    return layer, report
