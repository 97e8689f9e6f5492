"""Avatar tool → layers/avatar_<id>.usda: a UsdSkel avatar with labels.

The body is MakeHuman's CC0 mesh with its macro targets fitted to the requested sex, age,
stature, mass and build (:func:`humv_usd.human.body.build_body`), rigged with the CMU
MotionBuilder skeleton (:mod:`humv_usd.human.skeleton`) and written as UsdSkel
(:mod:`humv_usd.human.usdskel`)::

    /World/Humans/<id>            SkelRoot: placement (translate + rotateZ), HumvAvatarAPI,
                                  HumvLabelAPI, humv:label:cocoKeypoints (time-sampled)
        Skeleton                  UsdSkel.Skeleton, skel:animationSource -> Motion
        Motion                    UsdSkel.Animation (the standing rest pose without a motion)
        Body                      Mesh skinned to Skeleton (4 influences per vertex), skin
                                  material, primvars:humv:label:bodyRegion / jos3Segment

Everything below the SkelRoot is in the avatar frame (+Z up, facing -Y, soles at z = 0, the
same space as the skeleton's world transforms); the SkelRoot's transform places it.
The COCO keypoints are in that frame too (the SkelRoot's local space).
"""

from __future__ import annotations

import dataclasses

import numpy as np
from pxr import Gf, Sdf, UsdGeom

from humv_usd.catalog.garments import HELD_PROPS, LONG_GUNS, garment
from humv_usd.catalog.skin import skin_material_name
from humv_usd.geometry.mesh import fan_triangulate
from humv_usd.geometry.terrain import terrain_from_section
from humv_usd.human import crowd, usdskel
from humv_usd.human import labels as L
from humv_usd.human.basemesh import DEFAULT_FACING_DEG
from humv_usd.human.body import Body, build_body
from humv_usd.human.bvh import motion_from_bvh
from humv_usd.human.carry import apply_box_hold, apply_hold, apply_rifle_carry, carried_box
from humv_usd.human.chair import BOX, CHAIR, author_box, author_chair, posed_body_points
from humv_usd.human.clearance import arm_body, clear_arms
from humv_usd.human.motion import DEFAULT_SPEED, make_motion
from humv_usd.human.sequence import make_sequence_motion
from humv_usd.human.skeleton import (
    forward_kinematics,
    linear_blend_skinning,
    skeleton_for,
    skin_weights,
    skinning_matrices,
)
from humv_usd.scenario import Scenario
from humv_usd.scenario.ids import carries_box, instance_ids
from humv_usd.scenario.inputs import DERIVED_PER_PERSON, FRAMES
from humv_usd.usd.avatar import (
    AvatarParameters,
    write_avatar,
    write_body_labels,
    write_keypoints,
    write_metabolic_rate,
)
from humv_usd.usd.layers import SCOPES, finish, new_layer_stage, set_kind
from humv_usd.usd.mesh import define_mesh, label
from humv_usd.usd.paths import body_path, human_path, material_path, motion_path, props_path, skeleton_path

NAME = "avatar_{id}"  # one layer per [[human]]
#: what changes the avatar, and nothing else: the body (sex, age, stature, mass, build), the
#: fitness and activity it records, the motion (activity, speed, BVH file, the seed of the built-in
#: motion, whether the arms carry the rifle), the placement (position, heading, waypoints) and the
#: person's instance id; not the rest of the clothing, so scenarios that differ only in outfit
#: share one avatar layer (a sweep composes it once)
READS = (
    *FRAMES,
    "general.seed",
    *(
        f"human[{{id}}].{key}"
        for key in (
            "id",
            "sex",
            "age_yr",
            "stature_m",
            "mass_kg",
            "build",
            "proportions",
            "sitting_height_ratio",
            "skin_tone",
            "fitness",
            "activity",
            "bvh",
            "bvh_up_axis",
            "bvh_forward_axis",
            "speed_m_s",
            "segment",
        )
    ),
    "placement[{id}].position_m",
    "placement[{id}].heading_deg",
    "placement[{id}].waypoints_m",
    "@instanceId[{id}]",
    "@carriesRifle[{id}]",
    "@holds[{id}]",
    "@chairId[{id}]",
    "@boxId[{id}]",
    "@crowd[{id}]",
    "scene.terrain",
    "scene.ground.size_m",
)
UPSTREAM = ()
#: 27: children (< 20 yr) without a sitting_height_ratio get the Dutch reference median for the
#: sex and age (human.proportions.child_sitting_height_ratio; MakeHuman's macro: up to +0.025);
#: 26: the supporting knees of BVH clips (the crawl) held on the ground, the root re-planned over
#: them (human.limbs.lock_knees; knee slip 143 -> 0.3-2.3 mm per run); contact._bridge fades in
#: before a first run that a bridge follows (it jumped in);
#: 25: the supporting hands of BVH clips laid flat, palm down (human.limbs);
#: 24: bodies beyond the fat axis scaled more front to back than sideways (ANSUR II's waist depth
#: against breadth: human.body.split_horizontal_scale), humv:fit depthScale;
#: 23: BVH clips: hands that support the body (a crawl, a get-up) held on the ground (human.limbs);
#: 22: motion sequences may turn on the spot (segment turn), carry the box and sit on the chair
#: (sitChair segments): the box and the chair authored for them;
#: 21: the Props scope of the chair and the carried box is a Scope (was typeless: UsdSkel never
#: skinned the box, which stood at its rest place while the person walked on);
#: 20: below 30 fps a walk/run/carry/standing clip's humv:contact is the simulated motion's (a 1 fps
#: walk reported 3-4.6 m of slip: its kept frames merged a foot's stances);
#: 19: the seat and back roll without sliding between sitting and hook lying (poses);
#: 18: the carried box authored (human.carry.carried_box), the palms on its sides (apply_box_hold);
#: 17: hands on the ground held in the transitions out of and into hands-and-knees (poses._plant_hands);
#: 16: pose activities below 30 fps sampled from a 30 fps simulation (a 2 fps fall ended 30 cm off);
#: 15: arms holding something (box and rifle carries, held props) swivel their elbows out of the
#: trunk, hands kept in place (human.clearance.clear_arms mode "swivel");
#: 14: the BVH foot lock finds a run's skating stance feet (speed test for the body's pace) and
#: plants them at their mean place (DeepMimic run 77 -> 5 mm);
#: 13: a prop held in the right hand poses the right arm (human.carry.apply_hold); the chair of a
#: sitChair pose is authored (human.chair);
#: 12: planted feet of BVH motion locked (human.contact.lock_feet; DeepMimic slip 7-43 -> 0.2-5 mm),
#: human.segment (motion sequences, human/sequence.py);
#: 11: the upper arms are abducted where they would enter the trunk (human/clearance.py), except
#: in the box and rifle carries;
#: 10: motions below 30 fps sampled from a 30 fps (or faster) simulation (a 2 fps walk sat on the ground);
#: 9: standing arms 18 deg from the vertical, not 8 (the upper arm was inside the torso);
#: 8: the rifle carry smooths and re-pushes its offsets twice (no step > 6 cm after the push);
#: 7: human.sitting_height_ratio (leg axis, human/proportions.py);
#: 6: bodies beyond the weight macro follow the fat axis (human/fat.py), not a lateral scale;
#: 5: feet on the terrain (issue 30.1); 4: proportions and skin tone; 3: model kinds and extents
#: (2: reads only what changes the avatar)
VERSION = "27"


def build_one(scenario: Scenario, human: dict, motion=None) -> Sdf.Layer:
    """The avatar layer of one ``[[human]]``.

    ``motion``: None (the human's activity over the scenario's frames, from
    :func:`humv_usd.human.motion.make_motion` on flat ground) or an object with
    ``root_translation`` (F, 3) and ``local_rotations`` (F, J, 4) in the rig contract (see
    :mod:`humv_usd.human.usdskel`), e.g. from :func:`humv_usd.human.bvh.motion_from_bvh`;
    frame i is authored at time code i.
    """
    g = scenario["general"]
    place = next(p for p in scenario["placement"] if p["human"] == human["id"])
    body = build_body(
        human["sex"],
        human["age_yr"],
        human["stature_m"],
        human["mass_kg"],
        human["build"],
        human.get("proportions", 0.5),
        human.get("sitting_height_ratio"),
    )
    stage = new_layer_stage(
        g["fps"], scenario.frame_count, f"HumV-USD avatar layer for {human['id']} (UsdSkel, CMU rig)"
    )
    set_kind(UsdGeom.Scope.Define(stage, SCOPES["humans"]).GetPrim(), "group")
    root = usdskel.define_skel_root(stage, human_path(human["id"]))
    set_kind(root.GetPrim(), "component")
    root.AddTranslateOp().Set(Gf.Vec3d(*place["position_m"]))
    root.AddRotateZOp().Set(_avatar_rotation_deg(place))
    prim = root.GetPrim()
    _avatar_attributes(prim, human, body)
    if motion is None:
        motion = scenario_motion(scenario, human, place, body)
    _motion_attributes(prim, motion)
    label(prim, instance_ids(scenario)[f"human:{human['id']}"], "person")
    author_rig(stage, human["id"], body, motion, skin_material_name(human.get("skin_tone")))
    chair = (getattr(motion, "gait", None) or {}).get("chair")
    box = carries_box(human)
    if chair is not None or box:
        # a typed (imageable) parent: UsdSkel prunes untyped prims with their children, so a box
        # under a typeless Props was never skinned (it stood at its rest place in every frame)
        UsdGeom.Scope.Define(stage, props_path(human["id"]))
    if chair is not None:  # the chair a sitChair pose sits on (humv_usd.human.chair)
        skeleton = skeleton_for(body.points, body.groups)
        author_chair(
            stage,
            props_path(human["id"]).AppendChild(CHAIR),
            chair,
            posed_body_points(body, skeleton, motion),
            instance_ids(scenario).get(f"prop:{human['id']}:{CHAIR}"),
        )
    if box:  # the box in both hands
        skeleton = skeleton_for(body.points, body.groups)
        centre, size = carried_box(skeleton, body)
        author_box(
            stage,
            props_path(human["id"]).AppendChild(BOX),
            centre,
            size,
            skeleton_path(human["id"]),
            skeleton.index("Hips"),
            instance_ids(scenario).get(f"prop:{human['id']}:{BOX}"),
        )
    _author_extents(stage, human_path(human["id"]), scenario.frame_count)
    return finish(stage)


def _author_extents(stage, path, frames: int) -> None:
    """Per-frame ``extent`` of the SkelRoot (its skinned meshes) and of the Skeleton (its
    joints), as UsdSkel computes them, widened by :data:`EXTENT_PADDING_M`: viewers frame and
    cull the person by it (issue 27: no extent was authored)."""
    from pxr import Usd

    pad = Gf.Vec3f(EXTENT_PADDING_M)
    for prim in (stage.GetPrimAtPath(path), stage.GetPrimAtPath(path.AppendChild("Skeleton"))):
        boundable = UsdGeom.Boundable(prim)
        attr = boundable.CreateExtentAttr()
        for f in range(max(frames, 1)):
            code = Usd.TimeCode(f) if frames > 1 else Usd.TimeCode.Default()
            lo, hi = UsdGeom.Boundable.ComputeExtentFromPlugins(boundable, Usd.TimeCode(f))
            attr.Set([lo - pad, hi + pad], code)


#: Margin [m] on the person's extents: UsdSkel's skinned estimate fell 0.2 mm short of the top of
#: the head, and the garments (the clothing layer, over the body) stand up to a few cm off it.
EXTENT_PADDING_M = 0.05


def _avatar_rotation_deg(place: dict) -> float:
    """The SkelRoot's rotateZ: compass azimuth (clockwise from +y) -> counter-clockwise."""
    return float((DEFAULT_FACING_DEG - place["heading_deg"]) % 360.0)


def waypoints_in_avatar_frame(place: dict, start_xy) -> np.ndarray | None:
    """Hips ground track in the avatar frame: the rest hips, then the placement's waypoints
    (world [x, y]) moved into the frame of the SkelRoot (translate, then rotateZ)."""
    if not place["waypoints_m"]:
        return None
    phi = np.radians(_avatar_rotation_deg(place))
    world = np.asarray(place["waypoints_m"], dtype=float) - np.asarray(place["position_m"][:2])
    c, s = np.cos(phi), np.sin(phi)
    local = world @ np.array([[c, -s], [s, c]])  # rotate by -phi (row vectors)
    return np.vstack([np.asarray(start_xy, dtype=float)[None, :2], local])


def scenario_motion(scenario: Scenario, human: dict, place: dict, body: Body):
    """The human's motion over the scenario's frames: the BVH file if given, else the built-in
    activity (walk/run along the heading or the waypoints) on the terrain (:func:`avatar_ground`); with the arms in the
    rifle carry (:func:`humv_usd.human.carry.apply_rifle_carry`, kept clear of the body) if
    the human wears a long gun (:data:`humv_usd.catalog.garments.LONG_GUNS`: the rifle or
    the shotgun; the first one listed is carried); otherwise the arms abducted where they would
    enter the trunk (:func:`humv_usd.human.clearance.clear_arms`) and, with a prop held in the
    right hand (:data:`humv_usd.catalog.garments.HELD_PROPS`: phone read in front, phone_call at
    the ear, handbag by its handle; the first one listed), the right arm holding it
    (:func:`humv_usd.human.carry.apply_hold`). Arms whose hands hold something (the gun, the
    box of the ``carry`` activity, the held prop) are cleared by swivelling the elbow out
    instead (``clear_arms(..., mode="swivel")``: the hands stay where they are)."""
    g = scenario["general"]
    frames = scenario.frame_count
    skeleton = skeleton_for(body.points, body.groups)
    gun = next((g for g in human.get("clothing") or () if g in LONG_GUNS), None)
    held = next((g for g in human.get("clothing") or () if g in HELD_PROPS), None)

    def carry(motion):
        arms = avatar_arm_body(body, skeleton)
        if gun:  # hands on the gun: the elbows swing out of the trunk, the hands stay
            motion = apply_rifle_carry(motion, skeleton, body, prop=garment(gun).prop)
            return clear_arms(motion, skeleton, arms, mode="swivel")
        if carries_box(human):  # hands on the box (the activity or a sequence's carry): likewise
            motion = apply_box_hold(motion, skeleton, body)  # the palms on the box's sides
            return clear_arms(motion, skeleton, arms, mode="swivel")
        motion = clear_arms(motion, skeleton, arms)
        if not held:
            return motion
        # a prop held in the right hand (phone, phone_call, handbag): the right arm holds it
        motion = apply_hold(motion, skeleton, body, garment(held).prop)
        return clear_arms(motion, skeleton, arms, mode="swivel")

    if human.get("bvh"):
        motion = motion_from_bvh(
            human["bvh"],
            skeleton,
            g["fps"],
            frames,
            up_axis=human["bvh_up_axis"],
            forward_axis=human["bvh_forward_axis"],
            mass_kg=human["mass_kg"],
            body_points=body.points,
        )
        return carry(motion)
    segments = human.get("segment")
    if not segments and human["activity"] in WALKING and place.get("avoidance", "none") != "none":
        place = dict(place, waypoints_m=avoided_waypoints(scenario, human["id"]))
    # the motion model needs two frames at least; a one-frame scenario keeps the first
    common = dict(
        path=waypoints_in_avatar_frame(place, skeleton.rest_positions[0]),
        mass_kg=human["mass_kg"],
        body_points=body.points,
        seed=g["seed"],
        ground=avatar_ground(scenario, place),
    )
    if segments:  # a motion sequence: walk, stop, sit, get up, walk on ...
        i = next(k for k, h in enumerate(scenario["human"]) if h["id"] == human["id"])
        motion = make_sequence_motion(
            segments, skeleton, g["fps"], max(frames, 2), where=f"human[{i}].segment", **common
        )
    else:
        motion = make_motion(
            human["activity"], skeleton, g["fps"], max(frames, 2), speed_m_s=human.get("speed_m_s"), **common
        )
    if frames < 2:
        motion = dataclasses.replace(
            motion,
            root_translation=motion.root_translation[:frames],
            local_rotations=motion.local_rotations[:frames],
            metabolic_rate_w=motion.metabolic_rate_w[:frames],
        )
    return carry(motion)


def avatar_arm_body(body: Body, skeleton):
    """The body's :class:`humv_usd.human.clearance.ArmBody`: its mesh and skin binding as
    :func:`author_rig` authors them."""
    mesh = body.body_mesh()
    indices, weights = skin_weights(skeleton, mesh.vertex_ids, usdskel.INFLUENCES)
    triangles, _ = fan_triangulate(mesh.face_counts, mesh.face_indices)
    return arm_body(skeleton, mesh.points, triangles, indices, weights)


def avatar_ground(scenario: Scenario, place: dict):
    """The terrain's height in the person's avatar frame (translate to the placement, then
    rotateZ), as :func:`humv_usd.human.motion.make_motion` takes it, so that the feet stand and
    walk on the terrain (:mod:`humv_usd.geometry.terrain`); None on flat ground (z = 0 there)."""
    scene = scenario["scene"]
    if not scene:
        return None
    terrain = terrain_from_section(scene.get("terrain"), scene["ground"]["size_m"])
    if not terrain.has_relief and not any(terrain.slope_deg):
        return None
    phi = np.radians(_avatar_rotation_deg(place))
    c, s = np.cos(phi), np.sin(phi)
    x0, y0, z0 = (float(v) for v in place["position_m"])

    def height(x, y):
        x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
        return terrain.height(x0 + c * x - s * y, y0 + s * x + c * y) - z0

    return height


#: activities that walk a path (the others stand, sit or lie where they are placed)
WALKING = ("walk", "run", "carry")


def avoided_waypoints(scenario: Scenario, human_id: str) -> list:
    """The person's ground track (world [x, y] points) steered around everybody else by the
    social force model (:func:`humv_usd.human.crowd.avoid`) over the clip plus 2 s."""
    people = DERIVED_PER_PERSON["@crowd"](scenario, human_id)
    starts = np.array([p["position_m"] for p in people], dtype=float)
    speeds = np.array(
        [
            (p["speed_m_s"] or DEFAULT_SPEED[p["activity"]]) if p["activity"] in WALKING else 0.0
            for p in people
        ]
    )
    tracks = crowd.avoid(
        starts,
        [np.asarray(p["waypoints_m"], dtype=float).reshape(-1, 2) for p in people],
        speeds,
        scenario.frame_count / scenario["general"]["fps"] + 2.0,
        headings=np.radians([p["heading_deg"] for p in people]),
    )
    me = [p["human"] for p in people].index(human_id)
    return crowd.track_waypoints(tracks[me]).tolist()


def _motion_attributes(prim, motion) -> None:
    """Metabolic-rate schedule per frame and the clip's ground-contact report."""
    rate = getattr(motion, "metabolic_rate_w", None)
    if rate is not None:
        write_metabolic_rate(prim, rate)
    contact = getattr(motion, "contact", None) or {}
    report = {
        k: round(float(contact[k]), 5)
        for k in ("max_gap_m", "max_penetration_m", "max_slip_m")
        if k in contact
    }
    if report:
        prim.SetCustomDataByKey("humv:contact", report)


def _avatar_attributes(prim, human: dict, body: Body) -> None:
    person = AvatarParameters(
        human_id=human["id"],
        sex=human["sex"],
        age_yr=human["age_yr"],
        stature_m=human["stature_m"],
        mass_kg=human["mass_kg"],
        build=float(body.build),  # the muscle value: the clothing tool rebuilds the body
        fitness=human["fitness"],
        activity=(human.get("segment") or [human])[0]["activity"],
    )
    write_avatar(prim, person, round(body.body_surface_area_m2, 4))
    # how the request was met: measured values and the macro/scale fit (for reports and QA)
    requested = body.requested.get("sitting_height_ratio")
    prim.SetCustomDataByKey(
        "humv:fit",
        {
            # the clothing tool rebuilds the body with it (absent: MakeHuman's own legs)
            **({} if requested is None else {"sittingHeightRatioRequested": float(requested)}),
            "statureMeasured_m": round(body.stature_m, 5),
            "massFromVolume_kg": round(body.mass_kg, 4),
            "volume_m3": round(body.volume_m3, 6),
            "density_kg_m3": round(body.density_kg_m3, 2),
            "bodyFat_pct": round(body.body_fat_pct, 2),
            "fatAxis": round(body.fat, 6),
            "legAxis": round(body.legs, 6),
            "sittingHeightRatio": round(body.sitting_height_ratio, 6),
            "uniformScale": round(body.uniform_scale, 6),
            "lateralScale": round(body.lateral_scale, 6),
            "depthScale": round(body.depth_scale, 6),
            "macros": {k: round(float(v), 6) for k, v in vars(body.macros).items()},
        },
    )


def author_rig(stage, human_id: str, body: Body, motion=None, skin_material: str = "skin") -> None:
    """Skeleton, Motion, skinned Body with labels and the COCO keypoints under the SkelRoot
    ``human_path(human_id)`` (already defined); the Body is bound to the library material
    ``skin_material`` (``skin`` or a tone ``skin_I`` ... ``skin_VI``)."""
    skeleton = skeleton_for(body.points, body.groups)
    mesh = body.body_mesh()
    indices, weights = skin_weights(skeleton, mesh.vertex_ids, usdskel.INFLUENCES)
    pose = usdskel.as_pose(motion, skeleton)

    skel = usdskel.define_skeleton(stage, skeleton_path(human_id), skeleton)
    usdskel.define_animation(stage, motion_path(human_id), skeleton, pose)
    usdskel.bind_animation(skel.GetPrim(), motion_path(human_id))

    body_mesh = define_mesh(
        stage,
        body_path(human_id),
        mesh.points,
        mesh.face_counts,
        mesh.face_indices,
        material=material_path(skin_material),
    )
    usdskel.bind_mesh(body_mesh.GetPrim(), skeleton_path(human_id), indices, weights)
    author_face_labels(body_mesh.GetPrim(), mesh, skeleton, indices, weights)

    # COCO keypoints per frame: joints from FK, surface points skinned (only those vertices)
    world = forward_kinematics(skeleton, pose.local_rotations, pose.root_translation)
    skin = skinning_matrices(skeleton, world)
    surface = L.coco_surface_vertices()
    ids = np.array([surface[n] for n in L.COCO_SURFACE])
    sub = {n: k for k, n in enumerate(L.COCO_SURFACE)}
    keypoints = np.empty((pose.frame_count, len(L.COCO_KEYPOINTS), 3), dtype=np.float32)
    for f in range(pose.frame_count):
        posed = linear_blend_skinning(mesh.points[ids], indices[ids], weights[ids], skin[f])
        keypoints[f] = L.coco_keypoints(skeleton, world[f], posed, vertex_ids=sub)
    write_keypoints(stage.GetPrimAtPath(human_path(human_id)), keypoints, L.COCO_KEYPOINTS)


def author_face_labels(mesh_prim, mesh, skeleton, indices, weights) -> None:
    """Body-region and JOS-3 segment per face (uniform int primvars) with their name tables."""
    regions = L.body_regions(mesh, skeleton, indices, weights)
    segments = L.jos3_segments(regions)
    write_body_labels(mesh_prim, regions, L.BODY_REGION_NAMES, segments, L.JOS3_SEGMENTS)
