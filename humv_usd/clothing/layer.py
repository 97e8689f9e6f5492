"""Clothing tool → layers/clothing_<id>.usda: the garments a person wears, skinned, with air gaps.

For each garment of ``human["clothing"]`` (names of :data:`humv_usd.catalog.garments.GARMENTS`)::

    over /World/Humans/<id>                   the avatar layer's SkelRoot (its label: garments
                                              inherit the person's instance id and class)
        def Scope Clothing
            def Mesh <garment>                HumvClothingAPI (garment, ease, minimumGap,
                                              primvars:humv:clothing:airGap [m, vertex]),
                                              material:binding -> /World/Materials/<fabric>,
                                              points: a time-sampled point cache (posed, in
                                              the SkelRoot's space), no UsdSkel binding,
                                              primvars:humv:label:bodyRegion (uniform)

Props (``rifle``)::

    over /World/Humans/<id>
        def Scope Props
            def Mesh rifle                    closed rigid mesh, material:binding -> /World/
                                              Materials/<material>, UsdSkel binding to
                                              ../../Skeleton (100 % one joint, e.g. RightHand),
                                              HumvLabelAPI: its own instanceId (the
                                              scenario's ``prop:<id>:<name>`` entry of
                                              :func:`humv_usd.scene.layer.instance_ids`:
                                              after the scene objects) and class "prop",
                                              customData humv:prop (joint, clearance to the
                                              body per frame)

A prop is not a garment (no HumvClothingAPI, no air gap, no fix: the thermal tool treats it as
a fixed-temperature scene mesh). Without instance ids (``build_for_human`` called outside a
scenario) the prop gets only the class attribute and inherits the person's id.

Inputs: the person from the upstream stage's avatar layer (:mod:`humv_usd.clothing.person`:
HumvAvatarAPI parameters, Body rest points, skin weights and region labels, Skeleton bind pose;
:func:`humv_usd.usd.avatar.read_joint_transforms`: the motion), so an edited or replaced avatar
layer is dressed as it is; from the scenario only the person's ``clothing`` list, the props'
instance ids and the frame rate and count (:data:`READS`).

Garment motion is a plain point cache: the garment is fitted and skinned to the avatar's
Skeleton with weights transferred from the body (:mod:`humv_usd.clothing.fit`), posed per frame
by linear blend skinning, draped and fixed (:mod:`humv_usd.clothing.collide`), and the fixed
posed points are written as time-sampled ``points`` (time code = frame) in the SkelRoot's space
(= the Skeleton's space: the Skeleton and the Clothing scope carry no transform), without a
UsdSkel binding. Every consumer then reads the same points: the render and the thermal tool
(plain time-sampled reads), ``UsdSkel.BakeSkinning`` (leaves an unbound mesh alone) and Blender's
USD import (a mesh-sequence cache). Before VERSION 2 the garments were skinned meshes with
time-sampled *rest* points (``rest + A^-1 delta``); UsdSkel's own skinning read them, but
``BakeSkinning`` and Blender skin the default rest points and ignore the samples (65 mm for the
leggings and 80 mm for the T-shirt of examples/walk.toml). ``airGap`` is time-sampled the same
way. A person who does not move (one distinct pose) gets one value (the default, no samples).
A garment follows the avatar layer it was built on: compose rebuilds it when the avatar layer
changes (UPSTREAM); a motion edited in a stronger user layer does not move the garments.

The layer records how many garment vertices were inside the skin or closer than the minimum
gap before and after the fix, per garment (customData ``humv:clothing:fix``: the max over the
frames and int[] per frame), so a pipeline can fail on ``insideAfterMax > 0``; with a carried
rifle also the vertices nearer than the minimum gap to it before/after (``propBeforeMax``,
``propAfterMax``).
"""

from __future__ import annotations

import zlib

import numpy as np
from pxr import Sdf, Usd, UsdGeom, UsdShade, Vt

from humv_usd.catalog.dyes import garment_material, garment_print, print_faces, print_materials
from humv_usd.catalog.garments import garment
from humv_usd.clothing.collide import Simulation, dress, simulate
from humv_usd.clothing.fit import prepare
from humv_usd.clothing.person import read_person
from humv_usd.errors import InputError
from humv_usd.human import labels as L
from humv_usd.human import usdskel
from humv_usd.human.body import Body
from humv_usd.human.skeleton import Skeleton, skinning_matrices
from humv_usd.scenario import Scenario
from humv_usd.scenario.ids import instance_ids
from humv_usd.scenario.inputs import FRAMES
from humv_usd.usd.avatar import read_joint_transforms, write_air_gap, write_garment, write_garment_regions
from humv_usd.usd.layers import SCOPES, finish, new_layer_stage
from humv_usd.usd.mesh import bind_material, define_mesh, label, triangle_areas, write_class
from humv_usd.usd.paths import clothing_path, human_path, material_path, props_path, skeleton_path

#: Scenario values read: frame count and fps, the person's own entry (its ``clothing`` list) and
#: the instance ids (props follow the scene objects). The person (body, skin, skeleton, motion,
#: placement) comes from the upstream avatar layer (:mod:`humv_usd.clothing.person`).
NAME = "clothing_{id}"  # one layer per dressed [[human]]
READS = (*FRAMES, "human[{id}]", "@ids")
UPSTREAM = ("avatar_{id}",)
VERSION = "8"  # 8: head-only and other small garments (hair, shoes alone) take their air gap from ray casters over the body near them (clothing.collide._LocalCaster: the same triangles hit, float32 frames of their own: gaps differ by <= 6e-8 m); points unchanged; 7: garment prints (human.clothing_prints: PrintA/PrintB subsets, the mesh bound to their mix); 6: phone and the new phone_call and handbag held in the right hand, the palm on them (human/carry.held_rest_transform); 5: garments cut along smooth curves (level hems), footwear from the tights; 4: bodies with the fat axis (human/fat.py); 3: rebuilt with the avatar's proportions macro; 2: garments as a plain point cache (no skel binding)


def layer_name(human_id: str) -> str:
    return NAME.format(id=human_id)


def garment_path(human_id: str, garment: str) -> Sdf.Path:
    return clothing_path(human_id).AppendChild(garment)


def prop_path(human_id: str, prop: str) -> Sdf.Path:
    return props_path(human_id).AppendChild(prop)


# ---------------------------------------------------------------------------- authoring
def build_for_human(
    human: dict,
    body: Body,
    skeleton: Skeleton | None,
    motion_world_transforms: np.ndarray | None,
    garments,
    fps: float,
    frame_count: int,
    *,
    simulation_out: list | None = None,
    prop_ids: dict[str, int] | None = None,
    skinning: tuple[np.ndarray, np.ndarray] | None = None,
    face_regions: np.ndarray | None = None,
) -> Sdf.Layer:
    """The clothing layer of one person.

    human: the ``[[human]]`` table (``id`` is used); body: :func:`build_body`'s result for that
    person; skeleton: :func:`skeleton_for` of the body (None: computed);
    motion_world_transforms: (F, J, 4, 4) joint transforms in skeleton space
    (:func:`humv_usd.human.skeleton.forward_kinematics`), frame i at time code i, or None for
    the rest pose; garments: catalogue names; fps, frame_count: the scenario's.
    ``simulation_out``: if a list, the :class:`~humv_usd.clothing.collide.Simulation` is
    appended (counts, timings) for reports and benchmarks. ``prop_ids``: instance id per
    prop (catalogue name), e.g. from :func:`humv_usd.scenario.ids.instance_ids`.
    ``skinning``: the Body mesh's (joint indices, weights) as bound on the stage (None: the
    rig's weights).
    ``face_regions``: its body region per face (None: labelled as the avatar tool labels them).
    """
    rig = prepare(body, skeleton, skinning, face_regions)
    skeleton = rig.skeleton
    if motion_world_transforms is None:
        world = np.tile(np.eye(4), (1, len(skeleton.names), 1, 1))
        world[0, :, :3, 3] = skeleton.rest_positions
    else:
        world = np.asarray(motion_world_transforms, dtype=np.float64)
        if world.ndim != 4 or world.shape[1:] != (len(skeleton.names), 4, 4):
            raise ValueError(
                f"motion_world_transforms must be (F, {len(skeleton.names)}, 4, 4), got {world.shape}"
            )
        world = world[: max(frame_count, 1)]
        if np.allclose(world, world[:1], atol=1e-9):  # does not move: one pose
            world = world[:1]
    outfit = dress(rig, list(garments))
    sim = simulate(outfit, skinning_matrices(skeleton, world), fps=fps)
    if simulation_out is not None:
        simulation_out.append(sim)
    return author(
        human["id"],
        sim,
        fps,
        frame_count,
        prop_ids,
        human.get("clothing_colors"),
        human.get("hair_color"),
        prints=(human.get("clothing_prints"), human.get("clothing_print_colors")),
    )


def author(
    human_id: str,
    sim: Simulation,
    fps: float,
    frame_count: int,
    prop_ids: dict[str, int] | None = None,
    colours=None,
    hair_color: str | None = None,
    prints=(None, None),
) -> Sdf.Layer:
    """Write a :class:`Simulation` of one person's garments as a layer (see module doc);
    ``colours``: ``human.clothing_colors`` (garments bound to their fabric dyed that colour,
    :func:`humv_usd.catalog.dyes.garment_material`); ``hair_color``: ``human.hair_color``;
    ``prints``: (``human.clothing_prints``, ``human.clothing_print_colors``): a printed garment's
    faces in GeomSubsets ``PrintA``/``PrintB`` bound to its two dyes, the mesh to their
    area-weighted mix (:func:`humv_usd.catalog.dyes.print_faces`)."""
    names = ", ".join(a.name for a in sim.garments)
    stage = new_layer_stage(
        fps, frame_count, f"HumV-USD clothing layer for {human_id}: {names or 'no garments'}"
    )
    stage.OverridePrim(SCOPES["humans"])
    stage.OverridePrim(human_path(human_id))
    garments = [a for a in sim.garments if not a.fitted.garment.is_prop]
    props = [a for a in sim.garments if a.fitted.garment.is_prop]
    if garments or not props:
        UsdGeom.Scope.Define(stage, clothing_path(human_id))
    for anim in garments:
        _author_garment(stage, human_id, anim, colours, hair_color, prints)
    if props:
        UsdGeom.Scope.Define(stage, props_path(human_id))
    for anim in props:
        _author_prop(stage, human_id, anim, (prop_ids or {}).get(anim.name), colours)
    layer = finish(stage)
    # DefinePrim made the ancestors "def"; they belong to the avatar layer: only "over" here
    for path in (SCOPES["humans"], human_path(human_id)):
        layer.GetPrimAtPath(path).specifier = Sdf.SpecifierOver
    return layer


def _author_garment(
    stage: Usd.Stage, human_id: str, anim, colours=None, hair_color=None, prints=(None, None)
) -> None:
    fitted = anim.fitted
    g = fitted.garment
    frames = anim.posed.shape[0]
    static = frames == 1
    printed = garment_print(g.name, prints[0], prints[1], colours)
    if printed is not None:  # two dyes per face, the mesh bound to their mix (catalog.dyes)
        second = print_faces(
            printed[0], fitted.points, fitted.face_counts, fitted.face_indices, zlib.crc32(g.name.encode())
        )
        area = triangle_areas(fitted.points, fitted.face_counts, fitted.face_indices)
        share = float(area[second].sum()) / max(float(area.sum()), 1e-12)
        dye_a, dye_b, mix = print_materials(g.fabric, printed)
    mesh = define_mesh(
        stage,
        garment_path(human_id, g.name),
        anim.posed[0],
        fitted.face_counts,
        fitted.face_indices,
        material=material_path(mix if printed else garment_material(g.name, colours, hair_color)),
    )
    if printed is not None:
        UsdShade.MaterialBindingAPI.Apply(mesh.GetPrim()).SetMaterialBindSubsetsFamilyType(
            UsdGeom.Tokens.nonOverlapping
        )
        for name, faces, dye in (("PrintA", ~second, dye_a), ("PrintB", second, dye_b)):
            subset = UsdGeom.Subset.Define(stage, mesh.GetPath().AppendChild(name))
            subset.CreateElementTypeAttr(UsdGeom.Tokens.face)
            subset.CreateFamilyNameAttr(UsdShade.Tokens.materialBind)
            subset.CreateIndicesAttr(Vt.IntArray([int(i) for i in np.flatnonzero(faces)]))
            bind_material(subset.GetPrim(), material_path(dye))
        mesh.GetPrim().SetCustomDataByKey(
            "humv:print", {"kind": printed[0], "colours": list(printed[1:]), "shareB": round(share, 4)}
        )
    # an open shell: seen through sleeves, collars and hems, its inside must render too
    mesh.GetDoubleSidedAttr().Set(True)
    prim = mesh.GetPrim()
    write_garment(prim, g.name, g.ease, g.minimum_gap)
    write_air_gap(prim, anim.air_gap[:1] if static else anim.air_gap[:frames], time_sampled=not static)
    if not static:  # the point cache: posed points per frame (the default is frame 0's)
        points = mesh.GetPointsAttr()
        extent = mesh.GetExtentAttr()
        for f in range(frames):
            posed = anim.posed[f].astype(np.float32)
            points.Set(Vt.Vec3fArray.FromNumpy(posed), Usd.TimeCode(f))
            extent.Set(Vt.Vec3fArray.FromNumpy(np.array([posed.min(0), posed.max(0)])), Usd.TimeCode(f))
    write_garment_regions(prim, fitted.face_regions, L.BODY_REGION_NAMES)
    c = anim.counts
    prim.SetCustomDataByKey(
        "humv:clothing:fix",
        {
            "frames": frames,
            "insideBeforeMax": max(x.inside_before for x in c),
            "closeBeforeMax": max(x.close_before for x in c),
            "layeredBeforeMax": max(x.layered_before for x in c),
            "insideAfterMax": max(x.inside_after for x in c),
            "closeAfterMax": max(x.close_after for x in c),
            "layeredAfterMax": max(x.layered_after for x in c),
            "propBeforeMax": max(x.prop_before for x in c),
            "propAfterMax": max(x.prop_after for x in c),
            # between the vertices (edge midpoints, triangle centroids)
            "betweenInsideBeforeMax": max(x.between_inside_before for x in c),
            "betweenCloseBeforeMax": max(x.between_close_before for x in c),
            "betweenInsideAfterMax": max(x.between_inside_after for x in c),
            "betweenCloseAfterMax": max(x.between_close_after for x in c),
            "minDistance_m": round(min(x.min_distance_m for x in c), 6),
            "airGapMin_m": round(float(anim.air_gap.min()), 6),
            "airGapMedian_m": round(float(np.median(anim.air_gap)), 6),
            # per frame (index = time code)
            "insideBefore": Vt.IntArray([x.inside_before for x in c]),
            "closeBefore": Vt.IntArray([x.close_before for x in c]),
            "insideAfter": Vt.IntArray([x.inside_after for x in c]),
            "closeAfter": Vt.IntArray([x.close_after for x in c]),
        },
    )


def _author_prop(stage: Usd.Stage, human_id: str, anim, instance_id: int | None, colours=None) -> None:
    fitted = anim.fitted
    g = fitted.garment
    mesh = define_mesh(
        stage,
        prop_path(human_id, g.name),
        fitted.points,
        fitted.face_counts,
        fitted.face_indices,
        material=material_path(garment_material(g.name, colours)),
    )
    prim = mesh.GetPrim()
    usdskel.bind_mesh(prim, skeleton_path(human_id), fitted.joint_indices, fitted.joint_weights)
    if instance_id is None:
        write_class(prim, "prop")
    else:
        label(prim, instance_id, "prop")
    c = anim.counts
    info = {
        "catalogue": g.name,
        "joint": g.prop.joint,
        "placement": g.prop.placement,
        "frames": len(c),
        "insideMax": max(x.inside_before for x in c),
        "restMinDistance_m": round(c[0].min_distance_m, 6),
        "minDistance_m": round(min(x.min_distance_m for x in c), 6),
    }
    if anim.clearance is not None:  # the carry's clearance from the body, per frame
        info.update(
            {
                "bodyClearanceMin_m": round(float(anim.clearance.min()), 6),
                "bodyVerticesInsideMax": int(anim.body_inside.max()),
                "bodyClearance_m": Vt.FloatArray([round(float(x), 6) for x in anim.clearance]),
                "bodyVerticesInside": Vt.IntArray([int(x) for x in anim.body_inside]),
            }
        )
    prim.SetCustomDataByKey("humv:prop", info)


def build_one(scenario: Scenario, human: dict, upstream: Usd.Stage | None, garments=None) -> Sdf.Layer:
    """layers/clothing_<id>.usda for one ``[[human]]``.

    The person comes from the avatar layer on ``upstream`` (the in-memory composition of the
    layers before this one): body parameters, body mesh, skin weights, skeleton and motion
    (:func:`humv_usd.clothing.person.read_person`,
    :func:`humv_usd.usd.avatar.read_joint_transforms`); from the scenario only what is clothing
    input: ``human["clothing"]`` (``garments`` overrides it), the props' instance ids and the
    frame rate and count. A missing avatar (or one without HumvAvatarAPI) is one InputError.
    """
    if upstream is None:
        raise InputError(
            f"clothing of {human['id']!r}: needs the composed stage with its avatar layer (upstream)"
        )
    g = scenario["general"]
    names = list(human.get("clothing") or []) if garments is None else list(garments)
    person = read_person(upstream, human["id"])
    world = read_joint_transforms(upstream, human["id"], scenario.frame_count, g["fps"])
    ids = instance_ids(scenario)
    props = {
        garment(n).name: ids[f"prop:{human['id']}:{garment(n).name}"]
        for n in names
        if garment(n).is_prop and f"prop:{human['id']}:{garment(n).name}" in ids
    }
    return build_for_human(
        human,
        person.body,
        person.skeleton,
        world,
        names,
        g["fps"],
        scenario.frame_count,
        prop_ids=props,
        skinning=(person.joint_indices, person.joint_weights),
        face_regions=person.face_regions,
    )


def build(scenario: Scenario, upstream: Usd.Stage | None) -> dict[str, Sdf.Layer]:
    """One layer per person who wears anything: {``clothing_<id>``: layer}."""
    return {
        layer_name(h["id"]): build_one(scenario, h, upstream) for h in scenario["human"] if h.get("clothing")
    }
