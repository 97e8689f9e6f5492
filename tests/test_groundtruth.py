"""Ground truth: exact labels vs an independent ray cast, references/instancing, boxes, keypoints,
annotator selection. Small hand-built stages (64x48), one render per module fixture."""

from __future__ import annotations

import json

import numpy as np
import OpenImageIO as oiio
import pytest
from numpy.testing import assert_allclose
from pxr import Gf, Sdf, Usd, UsdGeom, UsdShade, Vt
from test_render import add_camera
from test_render import new_stage as _new_stage
from test_render import read_exr as _read_exr

from humv_usd.errors import InputError
from humv_usd.geometry.camera import Camera, CameraPose
from humv_usd.groundtruth import annotators as A
from humv_usd.groundtruth import boxes as B
from humv_usd.groundtruth import keypoints as K
from humv_usd.groundtruth import labels as GL
from humv_usd.human import labels as AL
from humv_usd.pipeline.render import render_stage
from humv_usd.usd import avatar as UA

W, H = 64, 48


# --- stage building (attributes by name, as a DCC would author them) --------------------------


def new_stage(path):
    return _new_stage(path, sky_k=260.0)


def material(stage, path, eps):
    m = UsdShade.Material.Define(stage, path)
    m.GetPrim().CreateAttribute("humv:material:wavelengths", Sdf.ValueTypeNames.FloatArray).Set(
        Vt.FloatArray([1.0, 20.0])
    )
    m.GetPrim().CreateAttribute("humv:material:emissivity", Sdf.ValueTypeNames.FloatArray).Set(
        Vt.FloatArray([eps, eps])
    )
    return m


def mesh(stage, path, points, counts, indices, mat, temps, instance_id=None, cls=None):
    m = UsdGeom.Mesh.Define(stage, path)
    m.CreatePointsAttr(Vt.Vec3fArray([Gf.Vec3f(*map(float, p)) for p in points]))
    m.CreateFaceVertexCountsAttr(Vt.IntArray([int(c) for c in counts]))
    m.CreateFaceVertexIndicesAttr(Vt.IntArray([int(i) for i in indices]))
    prim = m.GetPrim()
    UsdShade.MaterialBindingAPI.Apply(prim).Bind(mat)
    temps = np.broadcast_to(np.asarray(temps, dtype=float), (len(counts),))
    UsdGeom.PrimvarsAPI(prim).CreatePrimvar(
        "humv:thermal:temperature", Sdf.ValueTypeNames.FloatArray, UsdGeom.Tokens.uniform
    ).Set(Vt.FloatArray(temps.tolist()))
    label(prim, instance_id, cls)
    return m


def label(prim, instance_id=None, cls=None):
    if instance_id is not None:
        prim.CreateAttribute("humv:label:instanceId", Sdf.ValueTypeNames.Int).Set(int(instance_id))
    if cls is not None:
        prim.CreateAttribute("humv:label:class", Sdf.ValueTypeNames.Token).Set(cls)


def grid_quad(x0, x1, y0, y1, z, n):
    """n x n quads of a horizontal rectangle facing +Z."""
    xs, ys = np.linspace(x0, x1, n + 1), np.linspace(y0, y1, n + 1)
    pts = [(x, y, z) for y in ys for x in xs]
    idx = []
    for j in range(n):
        for i in range(n):
            a = j * (n + 1) + i
            idx += [a, a + 1, a + n + 2, a + n + 1]
    return pts, [4] * n * n, idx


def wall(x0, x1, z0, z1, y):
    """Rectangle at y facing -Y."""
    return [(x0, y, z0), (x1, y, z0), (x1, y, z1), (x0, y, z1)], [4], [0, 1, 2, 3]


def sphere_mesh(center, radius, subdivisions=2):
    import trimesh

    s = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
    return (s.vertices + np.asarray(center)).tolist(), [3] * len(s.faces), s.faces.ravel().tolist()


def camera(stage, name, eye, target, fov_x_deg=50.0, res=(W, H)):
    return add_camera(stage, name, eye, target, fov_x_deg=fov_x_deg, resolution=res)


def read_exr(path):
    return _read_exr(path)[1]


EYE, TARGET = (0.3, -6.0, 1.6), (0.0, 0.0, 0.9)


@pytest.fixture(scope="module")
def scene_render(tmp_path_factory):
    """Ground (fine grid, per-face temperatures), a labelled 'person' sphere with body regions, a
    box-ish wall partly hiding it."""
    tmp = tmp_path_factory.mktemp("gt")
    stage = new_stage(tmp / "stage.usda")
    concrete = material(stage, "/World/Materials/concrete", 0.9)
    skin = material(stage, "/World/Materials/skin", 0.98)
    pts, counts, idx = grid_quad(-10, 10, -10, 10, 0.0, 8)
    mesh(
        stage,
        "/World/Scene/ground",
        pts,
        counts,
        idx,
        concrete,
        280.0 + np.arange(64),
        instance_id=2,
        cls="ground",
    )
    root = UsdGeom.Xform.Define(stage, "/World/Humans/p1").GetPrim()
    label(root, 1, "person")
    pts, counts, idx = sphere_mesh((0.0, 0.0, 0.9), 0.6)
    nf = len(counts)
    body = mesh(
        stage, "/World/Humans/p1/Body", pts, counts, idx, skin, 300.0 + 0.01 * np.arange(nf)
    ).GetPrim()
    regions = 1 + np.arange(nf) % 19
    UsdGeom.PrimvarsAPI(body).CreatePrimvar(
        "humv:label:bodyRegion", Sdf.ValueTypeNames.IntArray, UsdGeom.Tokens.uniform
    ).Set(Vt.IntArray(regions.tolist()))
    pts, counts, idx = wall(-1.5, -0.1, 0.0, 2.0, -1.0)
    mesh(stage, "/World/Scene/wall", pts, counts, idx, concrete, 295.0, instance_id=3, cls="building")
    # keypoints on a SkelRoot-like prim (any prim carries them) with a transform
    kp_root = UsdGeom.Xform.Define(stage, "/World/Humans/p1/Keys")
    kp_root.AddTranslateOp().Set(Gf.Vec3d(0.0, 0.0, 0.9))
    kps = np.zeros((17, 3))
    kps[:] = (0.3, -0.55, 0.0)  # in front of the sphere's right half: visible
    kps[AL.COCO_KEYPOINTS.index("left_knee")] = (-0.4, -0.40, -0.3)  # behind the wall
    kps[AL.COCO_KEYPOINTS.index("right_ankle")] = (30.0, 0.0, 0.0)  # outside the image
    kps[AL.COCO_KEYPOINTS.index("nose")] = (0.3, 0.55, 0.0)  # on the far side
    kp_root.GetPrim().CreateAttribute(UA.COCO_KEYPOINTS_ATTR, Sdf.ValueTypeNames.Point3fArray).Set(
        Vt.Vec3fArray.FromNumpy(kps.astype(np.float32)), 0
    )
    camera(stage, "cam", EYE, TARGET)
    stage.Save()
    manifest = render_stage(tmp / "stage.usda", tmp / "out", spp=1)
    return tmp, manifest, read_exr(tmp / "out" / "cam" / "0000.exr")


def _world_triangles(stage_path):
    """Every rendered triangle in world space with its mesh path and authored face (own code)."""
    stage = Usd.Stage.Open(str(stage_path))
    tris, owner, face = [], [], []
    for prim in stage.Traverse(Usd.TraverseInstanceProxies()):
        if not prim.IsA(UsdGeom.Mesh):
            continue
        m = UsdGeom.Mesh(prim)
        xf = np.array(UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(0), dtype=float)
        p = np.asarray(m.GetPointsAttr().Get(), dtype=float) @ xf[:3, :3] + xf[3, :3]
        start = 0
        for f, c in enumerate(m.GetFaceVertexCountsAttr().Get()):
            ids = m.GetFaceVertexIndicesAttr().Get()[start : start + c]
            for k in range(1, c - 1):
                tris.append(p[[ids[0], ids[k], ids[k + 1]]])
                owner.append(str(prim.GetPath()))
                face.append(f)
            start += c
    return np.array(tris), owner, np.array(face)


def _pixel_rays(eye, target, fov_x_deg=50.0):
    eye, target = np.asarray(eye, float), np.asarray(target, float)
    fwd = (target - eye) / np.linalg.norm(target - eye)
    right = np.cross(fwd, (0, 0, 1.0))
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    tx = np.tan(np.radians(fov_x_deg) / 2)
    u = ((np.arange(W) + 0.5) / W * 2 - 1) * tx
    v = (1 - (np.arange(H) + 0.5) / H * 2) * tx * H / W
    uu, vv = np.meshgrid(u, v)
    d = fwd + uu[..., None] * right + vv[..., None] * up
    return d / np.linalg.norm(d, axis=-1, keepdims=True), fwd


def _gouraud(tris, owner, face_value, hit_tri, points, crease_deg=60.0, gain_steps=1):
    """Per hit point: its triangle's corner values (the angle-weighted mean of the faces of the
    same mesh around the welded vertex within ``crease_deg``; Thuermer & Wuethrich 1998), each
    then scaled ``gain_steps`` times by its ring's one-ring gain (the same weighted sum of the
    faces' own values over that of their corners' means: the render's shadowed term, issue 25),
    interpolated barycentrically (trimesh; NaN where nothing is hit)."""
    import trimesh

    out = np.full(len(hit_tri), np.nan)
    owner = np.asarray(owner)
    for name in np.unique(owner):
        idx = np.flatnonzero(owner == name)
        local = {g: i for i, g in enumerate(idx)}
        m = trimesh.Trimesh(tris[idx].reshape(-1, 3), np.arange(3 * len(idx)).reshape(-1, 3), process=False)
        m.merge_vertices()
        faces, angles, normals, vf = m.faces, m.face_angles, m.face_normals, m.vertex_faces
        value = np.asarray(face_value, float)[idx]
        rings = []
        for f in range(len(faces)):
            for v in faces[f]:
                around = vf[v][vf[v] >= 0]
                around = around[normals[around] @ normals[f] >= np.cos(np.radians(crease_deg))]
                rings.append((around, np.array([angles[g][list(faces[g]).index(v)] for g in around])))
        corner = np.array([np.sum(w * value[a]) / np.sum(w) for a, w in rings]).reshape(-1, 3)
        for _ in range(gain_steps):
            mean = corner.mean(axis=1)
            gain = [np.sum(w * value[a]) / np.sum(w * mean[a]) for a, w in rings]
            corner = corner * np.reshape(gain, (-1, 3))
        for p in np.flatnonzero(np.isin(hit_tri, idx)):
            f = local[hit_tri[p]]
            b = trimesh.triangles.points_to_barycentric(m.triangles[[f]], points[[p]])[0]
            out[p] = b @ corner[f]
    return out


def test_labels_agree_with_an_independent_ray_cast(scene_render):
    import trimesh

    tmp, manifest, ch = scene_render
    tris, owner, face = _world_triangles(tmp / "stage.usda")
    tm = trimesh.Trimesh(
        vertices=tris.reshape(-1, 3), faces=np.arange(len(tris) * 3).reshape(-1, 3), process=False
    )
    dirs, fwd = _pixel_rays(EYE, TARGET)
    origins = np.broadcast_to(np.asarray(EYE, float), (W * H, 3))
    loc, ray_idx, tri_idx = tm.ray.intersects_location(origins, dirs.reshape(-1, 3), multiple_hits=False)
    hit_tri = np.full(W * H, -1)
    hit_tri[ray_idx] = tri_idx
    depth = np.full(W * H, np.inf)
    depth[ray_idx] = (loc - np.asarray(EYE)) @ fwd
    ids = {"/World/Scene/ground": 2, "/World/Humans/p1/Body": 1, "/World/Scene/wall": 3}
    classes = {
        "/World/Scene/ground": "ground",
        "/World/Humans/p1/Body": "person",
        "/World/Scene/wall": "building",
    }
    expect_id = np.array([ids[owner[t]] if t >= 0 else 0 for t in hit_tri]).reshape(H, W)
    agree = ch["instance_id"] == expect_id
    fraction = agree.mean()
    print(f"label agreement with the trimesh/embree ray cast: {fraction:.5f} of {W * H} pixels")
    assert fraction >= 0.995, fraction  # edge pixels may differ by float rounding
    assert {0, 1, 2, 3} <= set(np.unique(expect_id).tolist())
    expect_cls = np.array([GL.CLASS_ID[classes[owner[t]]] if t >= 0 else 0 for t in hit_tri]).reshape(H, W)
    assert (ch["class_id"][agree] == expect_cls[agree]).all()
    kind = np.array(
        [GL.KIND_ID["skin" if "Body" in owner[t] else "scene"] if t >= 0 else 0 for t in hit_tri]
    ).reshape(H, W)
    assert (ch["material_kind"][agree] == kind[agree]).all()
    # same triangle -> the same authored face: temperature and body region exact
    tri2d = hit_tri.reshape(H, W)
    body = agree & (expect_id == 1)
    assert (ch["body_region"][body] == 1 + face[tri2d[body]] % 19).mean() > 0.99
    # the surface temperature is the faces' temperatures shaded smooth as the render shades
    # them (Gouraud, corners weighted by their angles, 60 deg creases, one one-ring gain step),
    # computed here with trimesh at the independent ray cast's hit points (plain Gouraud
    # agrees on 1 % of these pixels)
    face_k = np.array([(300.0 + 0.01 * f) if "Body" in o else (280.0 + f) for o, f in zip(owner, face)])
    hit_xyz = np.full((W * H, 3), np.nan)
    hit_xyz[ray_idx] = loc
    smooth = _gouraud(tris, owner, face_k, hit_tri, hit_xyz).reshape(H, W)
    ground = agree & (expect_id == 2)
    for region in (body, ground):
        assert (np.abs(ch["surface_temperature"][region] - smooth[region]) < 1e-3).mean() > 0.99
    # ... which is not the flat faces' value where the faces differ
    flat = face_k[tri2d[body]]
    assert np.abs(smooth[body] - flat).max() > 0.01
    # JOS-3 segment from the region when not authored; -1 off the body
    seg = ch["jos3_segment"]
    assert (seg[expect_id == 0] == GL.NO_SEGMENT).all()
    assert_allclose(seg[body], GL._REGION_TO_SEGMENT[ch["body_region"][body].astype(int)])
    # depth, normals (world space, unit, facing the camera for these front faces), emissivity
    hit = agree & (expect_id > 0)
    assert_allclose(ch["depth"][hit], depth.reshape(H, W)[hit], rtol=1e-4)
    n = np.stack([ch["normal_x"], ch["normal_y"], ch["normal_z"]], -1)
    tri = tris[tri2d[hit]]
    fn = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    fn /= np.linalg.norm(fn, axis=1, keepdims=True)
    assert (np.abs(np.sum(n[hit] * fn, axis=1) - 1) < 1e-3).mean() > 0.99
    assert_allclose(ch["emissivity"][expect_id == 1][agree[expect_id == 1]], 0.98, rtol=1e-6)
    assert np.isnan(ch["surface_temperature"][expect_id == 0]).all()
    gt = manifest["ground_truth"]
    assert gt["annotators"] == list(A.DEFAULT_ANNOTATORS) and gt["source"] == "default"
    assert gt["timings_s"]["total"] > 0 and gt["cost_relative_to_render"] > 0


def test_objects_boxes_occlusion_and_keypoints(scene_render):
    tmp, _, ch = scene_render
    doc = json.loads((tmp / "out" / "cam" / "0000.objects.json").read_text())
    objs = {o["instance_id"]: o for o in doc["objects"]}
    person, wall_obj = objs[1], objs[3]
    assert person["class"] == "person" and person["prim"] == "/World/Humans/p1"
    assert wall_obj["class"] == "building"
    mask = ch["instance_id"] == 1
    rows, cols = np.nonzero(mask)
    assert person["box_visible"] == [cols.min(), rows.min(), cols.max() + 1, rows.max() + 1]
    # the full box bounds the whole sphere: contains the visible one, and is larger on the wall side
    fb = person["box_full"]
    vb = person["box_visible"]
    assert fb[0] <= vb[0] + 1e-9 and fb[1] <= vb[1] + 1 and fb[2] >= vb[2] - 1 and fb[3] >= vb[3] - 1
    assert fb[0] < vb[0] - 2  # the wall hides the sphere's left part
    # the icosphere's vertices lie on the sphere: its world AABB is the sphere's
    assert_allclose(person["box_3d"]["min"], [-0.6, -0.6, 0.3], atol=1e-5)
    assert_allclose(person["box_3d"]["max"], [0.6, 0.6, 1.5], atol=1e-5)
    # oriented box: z extent exact, footprint inside the sphere's square, corners projected by
    # the render's camera model (the same object record reaches coco.json)
    ob = person["box_3d_oriented"]
    assert_allclose([ob["center"][2], ob["size"][2]], [0.9, 1.2], atol=1e-5)
    assert 1.1 < ob["size"][1] <= ob["size"][0] <= 1.2 + 1e-5 and -np.pi / 2 < ob["yaw"] <= np.pi / 2
    cam = Camera.from_pose(
        CameraPose(
            np.array(EYE),
            (np.array(TARGET) - EYE) / np.linalg.norm(np.subtract(TARGET, EYE)),
            np.array([0.0, 0.0, 1.0]),
            50.0,
        ),
        W,
        H,
    )
    uv, _ = cam.project(np.array(ob["corners_world"]))
    assert ob["behind_camera"] == [False] * 8
    assert_allclose(np.array(ob["corners_image"]), uv, atol=1e-5)  # the stage's pose is float32
    coco = json.loads((tmp / "out" / "coco.json").read_text())
    [ann] = [a for a in coco["annotations"] if a["humv_instance_id"] == 1]
    assert ann["bbox_3d_oriented"] == ob and ann["bbox_3d"] == person["box_3d"]
    assert 0.05 < person["occlusion"] < 0.6
    assert person["unoccluded_pixels"] > person["visible_pixels"] == mask.sum()
    assert wall_obj["occlusion"] == 0.0
    kp = np.array(person["keypoints"]).reshape(17, 3)
    v = kp[:, 2]
    names = list(AL.COCO_KEYPOINTS)
    assert v[names.index("right_ankle")] == 0 and kp[names.index("right_ankle"), :2].tolist() == [0, 0]
    assert v[names.index("left_knee")] == 1  # behind the wall
    assert v[names.index("nose")] == 1  # the sphere's own front is in front of it
    # the visible ones follow the rule: same person, one of the keypoint's regions at its pixel
    for k, name in enumerate(names):
        if v[k] != 2:
            continue
        c, r = int(kp[k, 0]), int(kp[k, 1])
        allowed = {AL.REGION_ID[x] for x in K.KEYPOINT_REGIONS[name]}
        assert ch["instance_id"][r, c] == 1 and int(ch["body_region"][r, c]) in allowed
    assert (v == 2).sum() >= 1


def test_masks_pngs(scene_render):
    tmp, _, ch = scene_render
    inp = oiio.ImageInput.open(str(tmp / "out" / "cam" / "0000.region_ids.png"))
    ids = np.rint(inp.read_image("float")[..., 0] * 255).astype(int)
    inp.close()
    assert (ids == ch["body_region"]).all()
    inp = oiio.ImageInput.open(str(tmp / "out" / "cam" / "0000.instance.png"))
    rgb = np.rint(inp.read_image("float") * 255).astype(int)
    inp.close()
    assert rgb.shape == (H, W, 3)
    assert (rgb[ch["instance_id"] == 0] == 0).all()
    colours = {tuple(rgb[ch["instance_id"] == i][0]) for i in (1, 2, 3)}
    assert len(colours) == 3  # distinct per instance


def test_references_and_instancing_get_their_own_labels(tmp_path):
    asset = Usd.Stage.CreateNew(str(tmp_path / "asset.usda"))
    UsdGeom.SetStageUpAxis(asset, UsdGeom.Tokens.z)
    root = UsdGeom.Xform.Define(asset, "/Asset")
    asset.SetDefaultPrim(root.GetPrim())
    mat = material(asset, "/Asset/Looks/paint", 0.9)
    pts, counts, idx = wall(-0.5, 0.5, 0.0, 1.0, 0.0)
    mesh(asset, "/Asset/Geom/panel", pts, counts, idx, mat, 300.0)
    asset.Save()

    stage = new_stage(tmp_path / "stage.usda")
    for name, x, ident, cls, instanceable in (
        ("ref", -1.5, 7, "vehicle", False),
        ("inst_a", 0.0, 8, "building", True),
        ("inst_b", 1.5, 9, "other", True),
    ):
        prim = UsdGeom.Xform.Define(stage, f"/World/Scene/{name}").GetPrim()
        prim.GetReferences().AddReference(str(tmp_path / "asset.usda"))
        UsdGeom.Xformable(prim).AddTranslateOp().Set(Gf.Vec3d(x, 0.0, 0.0))
        label(prim, ident, cls)
        prim.SetInstanceable(instanceable)
    camera(stage, "cam", (0.0, -5.0, 0.5), (0.0, 0.0, 0.5), fov_x_deg=60.0)
    stage.Save()
    assert (
        Usd.Stage.Open(str(tmp_path / "stage.usda"))
        .GetPrimAtPath("/World/Scene/inst_a/Geom/panel")
        .IsInstanceProxy()
    )
    manifest = render_stage(tmp_path / "stage.usda", tmp_path / "out", spp=1, annotators=["semantic", "coco"])
    ch = read_exr(tmp_path / "out" / "cam" / "0000.exr")
    cols = {i: np.nonzero(ch["instance_id"] == i)[1] for i in (7, 8, 9)}
    assert all(c.size > 50 for c in cols.values())
    assert cols[7].max() < cols[8].min() and cols[8].max() < cols[9].min()  # left to right
    for i, cls in ((7, "vehicle"), (8, "building"), (9, "other")):
        assert (ch["class_id"][ch["instance_id"] == i] == GL.CLASS_ID[cls]).all()
    coco = json.loads((tmp_path / "out" / "coco.json").read_text())
    got = {a["humv_instance_id"]: (a["humv_prim"], a["category_id"]) for a in coco["annotations"]}
    assert got == {
        7: ("/World/Scene/ref", GL.CLASS_ID["vehicle"]),
        8: ("/World/Scene/inst_a", GL.CLASS_ID["building"]),
        9: ("/World/Scene/inst_b", GL.CLASS_ID["other"]),
    }
    assert manifest["ground_truth"]["annotators"] == ["semantic", "coco"]


def test_only_requested_annotators_run(tmp_path):
    stage = new_stage(tmp_path / "stage.usda")
    mat = material(stage, "/World/Materials/m", 0.9)
    pts, counts, idx = wall(-5, 5, -5, 5, 3.0)
    mesh(stage, "/World/Scene/w", pts, counts, idx, mat, 300.0, instance_id=4)
    camera(stage, "cam", (0.0, 0.0, 0.0), (0.0, 1.0, 0.0), res=(16, 12))
    stage.GetRootLayer().customLayerData = {A.STAGE_KEY: Vt.StringArray(["normal"])}
    stage.Save()
    m = render_stage(tmp_path / "stage.usda", tmp_path / "out", spp=1)
    ch = read_exr(tmp_path / "out" / "cam" / "0000.exr")
    assert {"normal_x", "normal_y", "normal_z"} <= set(ch)
    assert not {"class_id", "body_region", "surface_temperature"} & set(ch)
    assert_allclose(ch["normal_y"], -1.0, atol=1e-6)
    assert m["ground_truth"]["annotators"] == ["normal"] and m["ground_truth"]["source"] == "stage"
    assert set(m["ground_truth"]["timings_s"]) == {"ray_cast", "normal", "total"}
    files = {p.name for p in (tmp_path / "out").rglob("*")}
    assert not files & {"coco.json", "regions.json", "0000.objects.json", "0000.instance.png"}
    # an argument overrides the stage; requirements come along; bad names are one-line errors
    assert A.resolve(["regions"]) == ("body_region", "regions")
    with pytest.raises(InputError, match=r"annotators\[1\] = 'boxez'.*allowed annotators"):
        A.resolve(["normal", "boxez"])


def test_scenario_annotations_reach_the_stage(raw, tmp_path):
    from humv_usd.pipeline.compose import root_layer
    from humv_usd.scenario.load import validate

    raw["annotations"] = {"annotators": ["coco", "keypoints"]}
    scenario = validate(raw)
    layer = root_layer(scenario, [])
    assert list(layer.customLayerData[A.STAGE_KEY]) == ["keypoints", "coco"]
    raw["annotations"] = {"annotators": ["cocoo"]}
    with pytest.raises(InputError, match="annotations.annotators"):
        root_layer(validate(raw), [])
    del raw["annotations"]
    assert A.STAGE_KEY not in root_layer(validate(raw), []).customLayerData


@pytest.mark.slow
def test_avatar_keypoints_front_and_side(raw, tmp_path):
    """A composed person facing east, seen from the front (+x) and from his right (-y): from the
    front every keypoint is visible, from the side exactly the right-side ones (and the nose)."""
    from humv_usd.pipeline.compose import compose
    from humv_usd.scenario.load import validate

    raw["placement"][0]["heading_deg"] = 90.0
    raw["human"][0]["clothing"] = ["shorts"]
    cam = {
        "band": "LWIR",
        "resolution": [96, 160],
        "focal_length_mm": 6.0,
        "pixel_pitch_um": 17.0,
        "look_at_m": [0.0, 0.0, 0.9],
    }
    raw["sensor"] = [
        dict(cam, id="front", position_m=[6.0, 0.0, 1.0]),
        dict(cam, id="side", position_m=[0.0, -6.0, 1.0]),
    ]
    raw["atmosphere"]["model"] = "analytic"
    raw["annotations"] = {"annotators": ["keypoints"]}
    compose(validate(raw), tmp_path)
    m = render_stage(tmp_path / "stage.usda", tmp_path / "out", spp=1)
    assert m["ground_truth"]["annotators"] == ["keypoints"] and m["ground_truth"]["source"] == "stage"
    for view in ("front", "side"):
        [person] = [
            o
            for o in json.loads((tmp_path / "out" / view / "0000.objects.json").read_text())["objects"]
            if o["class"] == "person"
        ]
        v = dict(zip(AL.COCO_KEYPOINTS, person["keypoints"][2::3]))
        if view == "front":
            assert set(v.values()) == {2}, v
        else:
            assert v["nose"] == 2
            assert all(v[k] == 2 for k in v if k.startswith("right_")), v
            assert all(v[k] == 1 for k in v if k.startswith("left_")), v


# --- oriented 3D boxes (no render) -------------------------------------------------------------
def _box_cloud(rng, center, size, yaw, n=200):
    """The 8 corners of a yaw-only box plus n random points inside it (world space)."""
    inner = (rng.random((n, 3)) - 0.5) * np.asarray(size)
    c, s = np.cos(yaw), np.sin(yaw)
    inner = inner @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]]).T + center
    return np.concatenate([B.box_corners(center, size, yaw), inner])


@pytest.mark.parametrize(
    "yaw, size, expect_yaw",
    [
        (0.0, (3.0, 1.2, 1.8), 0.0),
        (0.7, (3.0, 1.2, 1.8), 0.7),
        (-1.2, (0.5, 0.2, 1.7), -1.2),
        (np.pi / 2, (2.0, 1.0, 1.0), np.pi / 2),  # the closed end of (-pi/2, pi/2]
        (-np.pi / 2, (2.0, 1.0, 1.0), np.pi / 2),  # the same box
        (2.5, (2.0, 1.0, 1.0), 2.5 - np.pi),  # turned by pi: the same box
        (0.3, (1.0, 3.0, 1.0), 0.3 - np.pi / 2),  # width > length: axes swap
        (1.0, (1.0, 1.0, 2.0), 1.0 - np.pi / 2),  # square footprint: yaw in (-pi/4, pi/4]
    ],
)
def test_oriented_box_recovers_yaw_and_size(yaw, size, expect_yaw):
    rng = np.random.default_rng(7)
    center = np.array([12.0, -4.0, 0.9])
    ob = B.box_3d_oriented(_box_cloud(rng, center, size, yaw))
    length, width = max(size[:2]), min(size[:2])
    assert_allclose(ob["size"], [length, width, size[2]], rtol=1e-12, atol=1e-12)
    assert_allclose(ob["yaw"], expect_yaw, rtol=0, atol=1e-12)
    assert -np.pi / 2 < ob["yaw"] <= np.pi / 2
    assert_allclose(ob["center"], center, atol=1e-12)
    # the corners are the input box's corners (as a set)
    d = np.linalg.norm(
        np.array(ob["corners_world"])[:, None] - B.box_corners(center, size, yaw)[None], axis=-1
    )
    assert d.min(axis=1).max() < 1e-9
    assert "corners_image" not in ob


def test_oriented_box_is_minimal_area_against_a_brute_force_yaw_search():
    rng = np.random.default_rng(3)
    pts = rng.normal(size=(300, 3)) * [2.0, 0.6, 0.5] @ np.array([[0.8, 0.6, 0], [-0.6, 0.8, 0], [0, 0, 1.0]])
    ob = B.box_3d_oriented(pts)
    area = ob["size"][0] * ob["size"][1]
    yaws = np.linspace(0.0, np.pi / 2, 20001)  # every rectangle is one of these, turned
    u = pts[:, 0] * np.cos(yaws)[:, None] + pts[:, 1] * np.sin(yaws)[:, None]
    v = -pts[:, 0] * np.sin(yaws)[:, None] + pts[:, 1] * np.cos(yaws)[:, None]
    brute = (u.max(1) - u.min(1)) * (v.max(1) - v.min(1))
    assert area <= brute.min() * (1 + 1e-12)  # never worse than any sampled yaw
    # and the grid gets within its resolution: |dA/dyaw| <= 2 D^2 (D the cloud's diameter in the
    # plane), the optimum at most half a step from a grid yaw
    diameter = np.ptp(pts[:, :2], axis=0).max() * np.sqrt(2)
    assert brute.min() - area <= 2 * diameter**2 * 0.5 * (yaws[1] - yaws[0])
    assert brute.min() <= area * (1 + 1e-4)
    # every point inside the box, and the footprint touches the points on all four sides
    c, s = np.cos(ob["yaw"]), np.sin(ob["yaw"])
    local = (pts - ob["center"]) @ np.array([[c, s, 0], [-s, c, 0], [0, 0, 1.0]]).T
    half = 0.5 * np.array(ob["size"])
    assert (np.abs(local) <= half + 1e-9).all()
    assert_allclose(np.abs(local).max(axis=0), half, rtol=1e-12)
    assert_allclose([local[:, k].max() for k in range(3)], half, rtol=1e-12)
    # degenerate input: collinear points give width 0 along the line, one point a zero box
    line = B.box_3d_oriented(np.array([[0.0, 0.0, 0.0], [1.0, 1.0, 0.5], [2.0, 2.0, 1.0]]))
    assert_allclose(line["size"], [2 * np.sqrt(2), 0.0, 1.0], atol=1e-12)
    assert_allclose(line["yaw"], np.pi / 4, atol=1e-12)
    assert B.box_3d_oriented(np.zeros((1, 3)))["size"] == [0.0, 0.0, 0.0]
    assert B.box_3d_oriented(np.zeros((0, 3))) is None


def test_oriented_box_corners_project_with_the_camera_model():
    pose = CameraPose(np.array([0.0, -6.0, 1.5]), np.array([0.0, 1.0, 0.0]), np.array([0.0, 0.0, 1.0]), 60.0)
    cam = Camera.from_pose(pose, 80, 60)
    rng = np.random.default_rng(5)
    # a box in view, and one straddling the camera plane (y = -6): its near corners are behind
    for center, expect_behind in (((0.5, 0.0, 0.9), [False] * 8), ((0.0, -6.2, 1.0), None)):
        ob = B.box_3d_oriented(_box_cloud(rng, np.array(center), (2.0, 1.0, 1.8), 0.4, n=50), cam)
        corners = np.array(ob["corners_world"])
        uv, depth = cam.project(corners)
        assert ob["behind_camera"] == (depth <= 0).tolist()
        if expect_behind is not None:
            assert ob["behind_camera"] == expect_behind
        else:
            assert 0 < sum(ob["behind_camera"]) < 8
        for k in range(8):
            if ob["behind_camera"][k]:
                assert ob["corners_image"][k] is None
                continue
            assert_allclose(ob["corners_image"][k], uv[k], rtol=1e-12)
            # inverse check: the pixel ray through the projected point passes through the corner
            ray = cam.pixel_rays(np.array(uv[k, 0] - 0.5), np.array(uv[k, 1] - 0.5))
            to_corner = (corners[k] - pose.origin) / np.linalg.norm(corners[k] - pose.origin)
            assert_allclose(ray, to_corner, atol=1e-12)
