"""``humv-usd check``: USD's own validators plus HumV layer rules, as checker functions.

usd-core 26.11 no longer ships ``UsdUtils.ComplianceChecker``: its rules moved into the
UsdValidation framework that ``usdchecker`` runs. We run every registered UsdValidation validator
(stage metadata, encapsulation, material bindings, composition errors, attribute types, ...)
and then our own rules. Each finding is one line: ``<rule>: <where>: <message>``.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from pxr import Pcp, Sdf, Tf, Usd, UsdGeom, UsdShade, UsdSkel, UsdValidation

from humv_usd.constants import TEMPERATURE_RANGE_K
from humv_usd.errors import InputError
from humv_usd.geometry.mesh import fan_triangulate
from humv_usd.geometry.raycast import first_faces, ray_caster
from humv_usd.usd import schemas as S
from humv_usd.usd.layers import SCOPES, broken_sublayers, open_root_layer, unfinished_set, usd_error_text
from humv_usd.usd.mesh import read_asset_source
from humv_usd.usd.paths import GROUND, body_path
from humv_usd.usd.sensor import stage_sensors
from humv_usd.usd.thermal import temperature_type_problem

#: the name of a person's body mesh under its SkelRoot (humv_usd.usd.paths.body_path)
BODY_NAME = body_path("p").name


def usd_validators(stage: Usd.Stage) -> list[str]:
    """Run all validators registered with UsdValidation (the successor of ComplianceChecker)."""
    registry = UsdValidation.ValidationRegistry()
    context = UsdValidation.ValidationContext(registry.GetOrLoadAllValidators())
    out = []
    for err in context.Validate(stage):
        if err.GetType() == UsdValidation.ValidationErrorType.Info:
            continue
        sites = [str(s.GetPrim().GetPath()) for s in err.GetSites() if s.IsPrim()]
        where = sites[0] if sites else "stage"
        message = " ".join(err.GetMessage().split())
        out.append(f"usd:{err.GetName()}: {where}: {message}")
    return out


def rule_root_layer(stage: Usd.Stage) -> list[str]:
    """The root layer holds sublayers and metadata only; conventions Z-up, metres, defaultPrim."""
    out = []
    root = stage.GetRootLayer()
    # a flattened stage or a usdz package holds everything in its root layer: fine when it has
    # no sublayers; with sublayers, prims there are edits outside the part layers
    if root.rootPrims and root.subLayerPaths:
        names = ", ".join(p.name for p in root.rootPrims)
        out.append(
            f"humv:rootLayer: {root.identifier}: holds prims ({names}); the root layer "
            "should only sublayer the part layers"
        )
    if UsdGeom.GetStageUpAxis(stage) != UsdGeom.Tokens.z:
        out.append(f"humv:upAxis: stage: upAxis is {UsdGeom.GetStageUpAxis(stage)}, expected Z")
    if not math.isclose(UsdGeom.GetStageMetersPerUnit(stage), 1.0):
        out.append(
            f"humv:metersPerUnit: stage: metersPerUnit is {UsdGeom.GetStageMetersPerUnit(stage)}, expected 1"
        )
    if not stage.GetDefaultPrim():
        out.append("humv:defaultPrim: stage: no valid defaultPrim")
    if root.HasStartTimeCode() and root.HasEndTimeCode() and root.endTimeCode < root.startTimeCode:
        out.append(  # the render refuses it too (pipeline.preflight)
            f"humv:timeRange: stage: endTimeCode {root.endTimeCode:g} < startTimeCode {root.startTimeCode:g}"
        )
    tcps = root.timeCodesPerSecond
    for name, value in (("timeCodesPerSecond", tcps), ("framesPerSecond", root.framesPerSecond)):
        if not (math.isfinite(value) and value > 0):  # the render refuses it too (pipeline.preflight)
            out.append(f"humv:timeCodes: stage: {name} = {value:g}, expected > 0")
    for sub in root.subLayerPaths:
        layer = Sdf.Layer.FindOrOpenRelativeToLayer(root, sub)  # check_stage found them all loadable
        if layer is not None and layer.timeCodesPerSecond != tcps:
            out.append(
                f"humv:timeCodes: {sub}: timeCodesPerSecond {layer.timeCodesPerSecond} "
                f"!= root {tcps} (USD would rescale its time samples)"
            )
    return out


def _times(attr: Usd.Attribute) -> list[Usd.TimeCode]:
    """The attribute's sample times as time codes (GetTimeSamples gives plain floats), or the
    default time when it has none."""
    samples = attr.GetTimeSamples()
    return [Usd.TimeCode(t) for t in samples] if samples else [Usd.TimeCode.Default()]


def _infrared(stage: Usd.Stage) -> bool:
    """Whether the stage has a sensor the render draws from emission (it then needs a
    temperature on every mesh); False when the sensors do not read (rule_sensors says why)."""
    try:
        return any(s.rendered and s.kind != "EO" and not s.is_reflective for s in stage_sensors(stage))
    except InputError:
        return False


def rule_meshes(stage: Usd.Stage) -> list[str]:
    """Per-face temperatures (uniform, one per face, finite, in range; present on every mesh when
    an infrared sensor renders) and bound materials with HumvMaterialAPI."""
    out = []
    lo, hi = TEMPERATURE_RANGE_K
    infrared = _infrared(stage)
    for prim in stage.Traverse(Usd.TraverseInstanceProxies(Usd.PrimDefaultPredicate)):
        if not prim.IsA(UsdGeom.Mesh):
            continue
        path = prim.GetPath()
        faces = len(UsdGeom.Mesh(prim).GetFaceVertexCountsAttr().Get() or [])
        primvar = UsdGeom.PrimvarsAPI(prim).GetPrimvar(S.TEMPERATURE_PRIMVAR.removeprefix("primvars:"))
        if infrared and not (primvar and primvar.HasAuthoredValue()):
            out.append(
                f"humv:temperature: {path}: no per-face temperature ({S.TEMPERATURE_PRIMVAR}), which "
                "an infrared render needs; fix: re-run compose so that the thermal tool writes one on "
                "every mesh (a mesh added in a user layer after compose gets none), or author it"
            )
        problem = temperature_type_problem(primvar.GetAttr()) if primvar else None
        if problem:
            out.append(f"humv:temperature: {path}: {problem}")
        elif primvar and primvar.HasAuthoredValue():
            if primvar.GetInterpolation() != UsdGeom.Tokens.uniform:
                out.append(
                    f"humv:temperature: {path}: interpolation "
                    f"{primvar.GetInterpolation()}, expected uniform (one value per face)"
                )
            for t in _times(primvar.GetAttr()):
                values = np.asarray(primvar.Get(t) or [], dtype=float)
                when = "" if t.IsDefault() else f" at time {t.GetValue()}"
                if len(values) != faces:
                    out.append(f"humv:temperature: {path}{when}: {len(values)} values for {faces} faces")
                elif len(values) and not (
                    np.all(np.isfinite(values)) and values.min() >= lo and values.max() <= hi
                ):
                    out.append(
                        f"humv:temperature: {path}{when}: values "
                        f"{values.min():.6g}..{values.max():.6g} K outside {lo:g}..{hi:g} K"
                    )
        material, _ = UsdShade.MaterialBindingAPI(prim).ComputeBoundMaterial()
        if not material:
            out.append(
                f"humv:material: {path}: no bound material; fix: bind a library material "
                "(/World/Materials/<name>), e.g. with a [[scene.asset]] `materials` pattern"
            )
            continue
        mprim = material.GetPrim()
        if not mprim.HasAPI(S.MATERIAL_API):
            out.append(
                f"humv:material: {mprim.GetPath()}: bound to {path} but has no {S.MATERIAL_API}; fix: "
                "bind a library material (/World/Materials/<name>) instead, e.g. with a "
                "[[scene.asset]] `materials` pattern"
            )
            continue
        wl = np.asarray(mprim.GetAttribute(S.MATERIAL_WAVELENGTHS).Get() or [], dtype=float)
        eps = np.asarray(mprim.GetAttribute(S.MATERIAL_EMISSIVITY).Get() or [], dtype=float)
        if len(wl) == 0 or len(wl) != len(eps):
            out.append(
                f"humv:material: {mprim.GetPath()}: {len(wl)} wavelengths and "
                f"{len(eps)} emissivities (need the same non-zero count)"
            )
        elif np.any(np.diff(wl) <= 0) or np.any((eps < 0) | (eps > 1)):
            out.append(
                f"humv:material: {mprim.GetPath()}: wavelengths must ascend and emissivity lie in 0..1"
            )
    return out


def rule_sensors(stage: Usd.Stage) -> list[str]:
    """The render's read of every sensor camera succeeds; cameras that lost their sensor
    attributes (e.g. in a DCC's export) while no camera has them are findings."""
    try:
        sensors = stage_sensors(stage)
    except InputError as exc:
        return [f"humv:sensor: {line}" for line in exc.problems]
    if sensors:
        return []
    cameras = [p for p in stage.Traverse() if p.IsA(UsdGeom.Camera)]
    fix = "fix: compose with a [[sensor]], or apply HumvSensorAPI (humv_usd.usd.sensor.write_sensor)"
    # no camera at all: a stage without sensors (e.g. for another renderer) is fine
    return [
        f"humv:sensor: {p.GetPath()}: a camera without {S.SENSOR_API} attributes (band, resolution, "
        f"response), which render ignores, and the stage has no other sensor; {fix}"
        for p in cameras
    ]


def _units(layer: Sdf.Layer) -> tuple[str | None, float | None]:
    """(upAxis, metersPerUnit) a layer authors (None where it does not)."""
    info = layer.pseudoRoot
    up = info.GetInfo(UsdGeom.Tokens.upAxis) if info.HasInfo(UsdGeom.Tokens.upAxis) else None
    mpu = info.GetInfo(UsdGeom.Tokens.metersPerUnit) if info.HasInfo(UsdGeom.Tokens.metersPerUnit) else None
    return up, mpu


def _z_up_metres(up, mpu) -> bool:
    """Unauthored counts as fine: only what a file says is checked."""
    return up in (None, UsdGeom.Tokens.z) and (mpu is None or math.isclose(mpu, 1.0))


def rule_assets(stage: Usd.Stage) -> list[str]:
    """Referenced files exist and are Z-up metres, or the referencing prim converts them (the
    scene tool records what it converts in customData humv:assetSource)."""
    out = []
    for err in stage.GetCompositionErrors():
        if isinstance(err, Pcp.ErrorInvalidAssetPath):
            site = err.rootSite.path if err.rootSite else "stage"
            out.append(
                f"humv:asset: {site}: {' '.join(str(err).split())}; fix: restore the file or correct "
                "the path (compose writes [[scene.asset]] files and site layers relative to the layer "
                "when they share a folder with the output, else absolute: move them together with the "
                "output, or re-run compose after moving them)"
            )
    root = stage.GetRootLayer()
    for layer in stage.GetLayerStack(includeSessionLayers=False):
        up, mpu = _units(layer)
        if layer != root and not _z_up_metres(up, mpu):
            out.append(
                f"humv:assetUnits: {layer.realPath or layer.identifier}: a sublayer with upAxis {up}, "
                f"metersPerUnit {mpu}; USD composes a sublayer's prims as they are (Z-up metres on this "
                "stage); fix: re-export it Z-up in metres, or bring it in as a [[scene.asset]] "
                "(units/up_axis)"
            )
    for prim in stage.Traverse():
        if not (prim.HasAuthoredReferences() or prim.HasAuthoredPayloads()):
            continue
        query = Usd.PrimCompositionQuery(prim)
        for arc in query.GetCompositionArcs():
            if (
                arc.GetArcType() not in (Pcp.ArcTypeReference, Pcp.ArcTypePayload)
                or arc.GetTargetNode().IsRootNode()
            ):
                continue
            layer = arc.GetTargetNode().layerStack.layers[0]
            up, mpu = _units(layer)
            if _z_up_metres(up, mpu):
                continue
            src = read_asset_source(prim) or {}
            corrected = src.get("upAxis") == (up or "Y") and math.isclose(
                src.get("metersPerUnit", -1.0), mpu if mpu is not None else 0.01
            )
            if not corrected:
                out.append(
                    f"humv:assetUnits: {prim.GetPath()}: references {layer.realPath or layer.identifier} "
                    f"(upAxis {up}, metersPerUnit {mpu}) without a conversion to Z-up metres; fix: bring "
                    "it in as a [[scene.asset]] (units/up_axis), or re-export it Z-up in metres"
                )
    return out


def rule_sensors_and_labels(stage: Usd.Stage) -> list[str]:
    out = []
    ids: dict[int, str] = {}
    for prim in stage.Traverse():
        path = prim.GetPath()
        if prim.HasAPI(S.SENSOR_API):
            res = prim.GetAttribute(S.SENSOR_RESOLUTION).Get()
            band = prim.GetAttribute(S.SENSOR_WAVELENGTH_RANGE).Get()
            if res is None or min(res) < 1:
                out.append(f"humv:sensor: {path}: resolution {res}, expected two integers >= 1")
            if band is None or not band[0] < band[1]:
                out.append(f"humv:sensor: {path}: wavelengthRange {band}, expected short < long")
        if prim.HasAPI(S.LABEL_API):
            iid = prim.GetAttribute(S.LABEL_INSTANCE_ID).Get()
            if iid is None or iid < 1:
                out.append(f"humv:label: {path}: instanceId {iid}, expected an integer >= 1")
            elif iid in ids:
                out.append(f"humv:label: {path}: instanceId {iid} also used by {ids[iid]}")
            else:
                ids[iid] = str(path)
    return out


def rule_people(stage: Usd.Stage) -> list[str]:
    """Every person (a SkelRoot with HumvAvatarAPI) has its skinned Body mesh: without it the
    render and the labels silently leave the person out."""
    out = []
    for prim in stage.Traverse():
        if not (prim.IsA(UsdSkel.Root) and prim.HasAPI(S.AVATAR_API)):
            continue
        body = prim.GetChild(BODY_NAME)
        if not (body and body.IsA(UsdGeom.Mesh)):
            out.append(
                f"humv:person: {prim.GetPath()}: no body mesh {prim.GetPath().AppendChild(BODY_NAME)} "
                "(a UsdGeom.Mesh); render would leave the person out"
            )
    return out


def rule_skinned_points(stage: Usd.Stage) -> list[str]:
    """A skinned mesh (UsdSkel binding with joint influences) must not carry time-sampled
    ``points``: standard skinning (``UsdSkel.BakeSkinning``, Blender's USD import, usdview)
    deforms the rest points and ignores the samples, so those consumers would not see the motion
    the samples hold (the clothing layer before its VERSION 2 wrote garments so)."""
    out = []
    for prim in stage.Traverse(Usd.TraverseInstanceProxies(Usd.PrimDefaultPredicate)):
        if not prim.IsA(UsdGeom.Mesh):
            continue
        binding = UsdSkel.BindingAPI(prim)
        skeleton = binding.GetInheritedSkeleton()
        joints = binding.GetJointIndicesPrimvar()
        if not (skeleton and joints and joints.HasAuthoredValue()):
            continue
        samples = UsdGeom.Mesh(prim).GetPointsAttr().GetNumTimeSamples()
        if samples > 1:
            out.append(
                f"humv:skinnedPoints: {prim.GetPath()}: skinned by {skeleton.GetPath()} and its points "
                f"are time-sampled ({samples} samples), which standard skinning (UsdSkel.BakeSkinning, "
                "Blender, usdview) ignores: they deform the rest points; fix: re-run compose (garments "
                "are plain point caches since clothing VERSION 2), or keep one of the two: remove the "
                "skel binding (skel:skeleton, primvars:skel:jointIndices/jointWeights) so the samples "
                "are the motion, or remove the points' time samples so the skeleton is"
            )
    return out


#: height [m] above a person's origin (the feet) tested for enclosure: about the chest
CHEST_M = 1.0
#: axis directions of the enclosure test's rays
_AXES = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)


def enclosed_in_scene_objects(stage: Usd.Stage, skip=()) -> list[str]:
    """Warning lines (not check findings: an indoor camera may be meant): a sensor camera, or a
    person's chest, that a scene object's meshes enclose (rays in all six axis directions hit
    that object) at the first frame; the render then shows the object's inside. Objects whose
    id is in ``skip`` (boxes, which the scenario's warnings cover) and the ground are left out
    (issue 26: an asset enclosing the camera and the person gave no warning, a box did)."""
    t = Usd.TimeCode(stage.GetStartTimeCode())
    points = {}
    for prim in stage.Traverse(Usd.TraverseInstanceProxies(Usd.PrimDefaultPredicate)):
        if prim.IsA(UsdGeom.Camera):
            xf = np.asarray(UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(t))
            points[f"camera {prim.GetPath()}"] = xf[3, :3]
    humans = stage.GetPrimAtPath(SCOPES["humans"])
    for person in humans.GetChildren() if humans else ():
        xf = np.asarray(UsdGeom.Xformable(person).ComputeLocalToWorldTransform(t))
        points[f"person {person.GetName()}"] = xf[3, :3] + [0.0, 0.0, CHEST_M]
    scene = stage.GetPrimAtPath(SCOPES["scene"])
    if not points or not scene:
        return []
    centres = np.array(list(points.values()), float)
    origins = np.repeat(centres, len(_AXES), axis=0)
    directions = np.tile(_AXES, (len(points), 1))
    out = []
    for obj in scene.GetChildren():
        if obj.GetPath() == GROUND or obj.GetName() in skip:
            continue
        pts, tris, n = [], [], 0
        for prim in Usd.PrimRange(obj, Usd.TraverseInstanceProxies(Usd.PrimDefaultPredicate)):
            if not prim.IsA(UsdGeom.Mesh):
                continue
            mesh = UsdGeom.Mesh(prim)
            p = np.asarray(mesh.GetPointsAttr().Get(t) or [], float).reshape(-1, 3)
            counts = np.asarray(mesh.GetFaceVertexCountsAttr().Get(t) or [], np.int64)
            if not len(p) or not len(counts):
                continue
            xf = np.asarray(UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(t))
            tri, _ = fan_triangulate(counts, np.asarray(mesh.GetFaceVertexIndicesAttr().Get(t), np.int64))
            pts.append(p @ xf[:3, :3] + xf[3, :3])
            tris.append(tri + n)
            n += len(p)
        if not pts:
            continue
        world = np.concatenate(pts)
        near = np.all((centres >= world.min(axis=0)) & (centres <= world.max(axis=0)), axis=1)
        if not near.any():  # outside its bounding box (most objects): no rays
            continue
        caster = ray_caster(world, np.concatenate(tris))
        hit = (first_faces(caster, origins, directions) >= 0).reshape(len(points), len(_AXES)).all(axis=1)
        out += [
            f"{what} is inside scene object {obj.GetName()!r} (its meshes surround it): the render "
            "shows the object's inside; move it out, or ignore this for an indoor view"
            for what, inside in zip(points, hit & near)
            if inside
        ]
    return out


RULES = (
    rule_root_layer,
    rule_meshes,
    rule_sensors,
    rule_assets,
    rule_sensors_and_labels,
    rule_people,
    rule_skinned_points,
)


def check_stage(path: str | Path) -> list[str]:
    """All findings for the stage at ``path`` (empty when clean).

    A root file that is missing or not USD raises InputError (bad input, exit 2). A sublayer
    that is missing or does not load is a finding naming its file (``humv:sublayer``); the other
    rules are then not run, since the stage USD would compose without that layer is not the
    stage compose wrote and its findings would mislead. A set of layers that is not one
    compose's is a finding too (``humv:layerSet``, :func:`humv_usd.usd.layers.unfinished_set`)."""
    root = open_root_layer(path)
    opened: list[Sdf.Layer] = []  # held: opening the stage does not parse them again
    broken = broken_sublayers(root, opened)
    if broken:
        return [f"humv:sublayer: {line}" for line in broken]
    mixed = [f"humv:layerSet: {line}" for line in unfinished_set(root)]
    try:
        stage = Usd.Stage.Open(root)
    except Tf.ErrorException as exc:
        return [f"humv:stage: {path}: USD cannot compose the stage ({usd_error_text(exc)})"]
    try:
        findings = usd_validators(stage)
    except Tf.ErrorException as exc:  # a validator that fails on this stage is a finding, not a crash
        findings = [f"usd:validators: stage: failed ({usd_error_text(exc)})"]
    findings = mixed + findings
    for rule in RULES:
        findings.extend(rule(stage))
    return findings
