"""Outputs in their ecosystems' conventions (issue 12, deliverable 6).

- EXR channel names: ``Z`` is depth (OpenImageIO's ``z_channel``), CIE XYZ under ``CIE.``, colour as
  ``R,G,B`` (the IR file: a grey preview), labels as ``label.*`` stored as uint32 and read back exact.
- Camera: OpenEXR's ``worldToCamera`` / ``worldToNDC`` in the headers and ``<sensor>/camera.json``
  (K, zero distortion, OpenCV R, t per frame). The references are independent of
  :class:`humv_usd.geometry.camera.Camera`: the stage's keypoints and camera prim, projected with
  the written K and R, t, land on the written 2D keypoints; the header matrices give the same
  pixels; the pinhole closed form u = cx + fx x / z.
"""

from __future__ import annotations

import json

import numpy as np
import OpenImageIO as oiio
import pytest
from numpy.testing import assert_allclose
from pxr import Gf, Sdf, Usd, UsdGeom, Vt
from test_groundtruth import label, material, mesh, sphere_mesh, wall
from test_render import H, W, add_camera
from test_render import new_stage as _new_stage
from test_render_eo import eo_camera, reflective
from test_render_radiometry import atmosphere_tables, plate, sun
from test_render_radiometry import new_stage as new_eo_stage

from humv_usd import images
from humv_usd.errors import InputError
from humv_usd.geometry.camera import Camera, CameraPose
from humv_usd.pipeline.render import render_stage
from humv_usd.render.cie import XYZ_TO_SRGB
from humv_usd.usd import avatar as UA
from humv_usd.usd.labels import MAX_INSTANCE_ID


def _oiio_channels(path):
    """Channels by EXR name, each in its stored type, read with OpenImageIO alone."""
    inp = oiio.ImageInput.open(str(path))
    spec = inp.spec()
    out = {
        n: inp.read_image(0, 0, i, i + 1, spec.channelformat(i))[..., 0]
        for i, n in enumerate(spec.channelnames)
    }
    inp.close()
    return spec, out


def _matrix(spec, name, shape=(4, 4)):
    return np.array(spec.getattribute(name), dtype=float).reshape(shape)


def test_ids_are_exact_uint32_and_z_is_depth(tmp_path):
    rng = np.random.default_rng(1)
    ids = rng.integers(0, MAX_INSTANCE_ID + 1, (8, 9)).astype(np.int64)
    ids[0, :4] = [0, 1, 2**24 - 3, MAX_INSTANCE_ID]
    depth = rng.uniform(1.0, 50.0, (8, 9))
    cie_z = rng.uniform(0.0, 1.0, (8, 9))
    images.write_exr(
        tmp_path / "a.exr", {"Z": cie_z, "depth": depth, "instance_id": ids, "jos3_segment": -np.ones((8, 9))}
    )
    spec, ch = _oiio_channels(tmp_path / "a.exr")
    assert spec.channelnames[spec.z_channel] == "Z"
    assert_allclose(ch["Z"], depth.astype(np.float32))
    assert_allclose(ch["CIE.Z"], cie_z.astype(np.float32))
    assert str(spec.channelformat(spec.channelnames.index("label.instance_id"))) == "uint"
    assert ch["label.instance_id"].dtype == np.uint32 and np.array_equal(ch["label.instance_id"], ids)
    assert (ch["label.jos3_segment"] == -1).all()  # signed: float32 (OpenEXR has no signed int)
    back = images.read_exr(tmp_path / "a.exr")
    assert set(back) == {"Z", "depth", "instance_id", "jos3_segment"}
    assert np.array_equal(back["instance_id"], ids)
    with pytest.raises(InputError, match="instance_id"):  # would not be stored exactly
        images.write_exr(tmp_path / "b.exr", {"instance_id": np.full((2, 2), 2**24 + 1)})
    assert not (tmp_path / "b.exr").exists()


def test_camera_matrices_closed_form():
    rng = np.random.default_rng(3)
    fwd = rng.normal(size=3)
    fwd /= np.linalg.norm(fwd)
    w, h, fov = 320, 200, 37.0
    cam = Camera.from_pose(CameraPose(rng.normal(size=3) * 5, fwd, np.array([0.0, 0.0, 1.0]), fov), w, h)
    pts = cam.origin + 10 * fwd + rng.normal(size=(50, 3))
    uv, z = cam.project(pts)
    # the pinhole closed form with fx = W / (2 tan(fov/2)), centre (W/2, H/2) (corner origin)
    k = cam.intrinsics()
    fx = w / (2 * np.tan(np.radians(fov) / 2))
    assert_allclose(k, [[fx, 0, w / 2], [0, fx, h / 2], [0, 0, 1]], rtol=1e-12)
    rot, t = cam.opencv_extrinsics()
    assert_allclose(rot @ rot.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(rot) == pytest.approx(1.0)  # right-handed x right, y down, z forward
    xc = pts @ rot.T + t
    assert_allclose(xc[:, 2], z, rtol=1e-12)
    assert_allclose((xc @ k.T)[:, :2] / xc[:, 2:], uv, atol=1e-9)
    # OpenEXR: row vectors; camera space x right, y up, z forward; NDC (0,0) top-left, (1,1) bottom-right
    hom = np.c_[pts, np.ones(len(pts))]
    cam_exr = hom @ cam.world_to_camera_exr()
    assert_allclose(cam_exr[:, :3], xc * [1, -1, 1], atol=1e-9)
    ndc = hom @ cam.world_to_ndc_exr()
    assert_allclose(ndc[:, :2] / ndc[:, 3:] * [w, h], uv, atol=1e-9)


def test_eo_file_reads_right_in_openimageio(tmp_path):
    """Depth is OpenImageIO's z channel (the plate 10 m below the camera), not CIE Z; the first
    three channels are R, G, B (linear sRGB of CIE.X/Y/Z); the header carries the camera."""
    stage = new_eo_stage(tmp_path / "s.usda")
    white = reflective(stage, "white", [0.3, 1.0], [0.8, 0.8])
    plate(stage, "/World/p", 1e3, 0.0, white, 300.0)
    eo_camera(stage, "eo", (0, 0, 10), (0, 0, 0), fov_x_deg=10.0)
    atmosphere_tables(stage, [0.3, 0.9, 4.0], solar=[1500.0] * 3)
    sun(stage, (0.3, 0.0, 1.0))
    stage.Save()
    manifest = render_stage(tmp_path / "s.usda", tmp_path / "out", spp=4)
    buf = oiio.ImageBuf(str(tmp_path / "out" / "eo" / "0000.exr"))
    spec = buf.spec()
    px = buf.get_pixels(oiio.FLOAT)
    assert spec.channelnames[spec.z_channel] == "Z"
    assert_allclose(px[..., spec.z_channel], 10.0, rtol=1e-5)  # depth along the axis
    names = list(spec.channelnames)
    assert names[:3] == ["R", "G", "B"] and spec.alpha_channel == -1
    xyz = np.stack([px[..., names.index(f"CIE.{c}")] for c in "XYZ"], axis=-1)
    assert xyz[..., 1].mean() > 0
    assert_allclose(px[..., :3], xyz @ np.asarray(XYZ_TO_SRGB).T, rtol=1e-4, atol=1e-9)
    assert not np.allclose(px[..., names.index("CIE.Z")], px[..., spec.z_channel])
    [rec] = manifest["eo_sensors"]
    assert rec["camera"] == "eo/camera.json"
    assert rec["channels"]["depth"]["exr"] == "Z" and rec["channels"]["Z"]["exr"] == "CIE.Z"
    cam_file = json.loads((tmp_path / "out" / "eo" / "camera.json").read_text())
    _header_agrees_with_camera_file(spec, cam_file, 0)
    # the camera straight down from 10 m: R maps world -z to camera +z, t = R (-origin)
    [frame] = cam_file["frames"]
    assert_allclose(np.array(frame["R"])[2], [0, 0, -1], atol=1e-6)
    assert_allclose(frame["t"], [0, 0, 10], atol=1e-5)


def _header_agrees_with_camera_file(spec, cam_file, frame):
    """worldToCamera / worldToNDC / humv:K of an EXR header against the camera file's K, R, t."""
    k = np.array(cam_file["K"])
    assert_allclose(_matrix(spec, "humv:K", (3, 3)), k, rtol=1e-6)
    [rec] = [f for f in cam_file["frames"] if f["frame"] == frame]
    rot, t = np.array(rec["R"]), np.array(rec["t"])
    pts = np.array(rec["camera_origin_m"]) + rot[2] * 7.0 + np.random.default_rng(0).normal(size=(20, 3))
    hom = np.c_[pts, np.ones(len(pts))]
    xc = pts @ rot.T + t
    assert_allclose(
        hom @ _matrix(spec, "worldToCamera"), np.c_[xc * [1, -1, 1], np.ones(len(pts))], atol=1e-4
    )
    ndc = hom @ _matrix(spec, "worldToNDC")
    uv = (xc @ k.T)[:, :2] / xc[:, 2:]
    assert_allclose(ndc[:, :2] / ndc[:, 3:] * [cam_file["width"], cam_file["height"]], uv, atol=1e-3)


EYE, TARGET = (0.3, -6.0, 1.6), (0.0, 0.0, 0.9)
EYE1 = (0.9, -5.5, 1.8)  # the camera moves between frame 0 and 1


@pytest.fixture(scope="module")
def ir_render(tmp_path_factory):
    """A labelled 'person' sphere with keypoints, a wall, an IR camera that moves over 2 frames."""
    tmp = tmp_path_factory.mktemp("exr")
    stage = _new_stage(tmp / "stage.usda", sky_k=260.0, end=1)
    UsdGeom.Scope.Define(stage, "/World/Environment")
    concrete = material(stage, "/World/Materials/concrete", 0.9)
    skin = material(stage, "/World/Materials/skin", 0.98)
    root = UsdGeom.Xform.Define(stage, "/World/Humans/p1").GetPrim()
    label(root, 1, "person")
    pts, counts, idx = sphere_mesh((0.0, 0.0, 0.9), 0.6)
    nf = len(counts)
    body = mesh(
        stage, "/World/Humans/p1/Body", pts, counts, idx, skin, 300.0 + 0.01 * np.arange(nf)
    ).GetPrim()
    UsdGeom.PrimvarsAPI(body).CreatePrimvar(
        "humv:label:bodyRegion", Sdf.ValueTypeNames.IntArray, UsdGeom.Tokens.uniform
    ).Set(Vt.IntArray((1 + np.arange(nf) % 19).tolist()))
    pts, counts, idx = wall(-1.5, -0.1, 0.0, 2.0, -1.0)
    mesh(stage, "/World/Scene/wall", pts, counts, idx, concrete, 295.0, instance_id=3, cls="building")
    kp_root = UsdGeom.Xform.Define(stage, "/World/Humans/p1/Keys")
    kp_root.AddTranslateOp().Set(Gf.Vec3d(0.0, 0.0, 0.9))
    kps = np.random.default_rng(5).uniform(-0.5, 0.5, (17, 3))
    kps[:, 1] = -0.62  # just in front of the sphere, seen by the camera
    kp_root.GetPrim().CreateAttribute(UA.COCO_KEYPOINTS_ATTR, Sdf.ValueTypeNames.Point3fArray).Set(
        Vt.Vec3fArray.FromNumpy(kps.astype(np.float32)), 0
    )
    cam = add_camera(stage, "cam", EYE, TARGET, fov_x_deg=50.0)
    op = cam.GetOrderedXformOps()[0]
    for frame, eye in ((0, EYE), (1, EYE1)):
        view = Gf.Matrix4d().SetLookAt(Gf.Vec3d(*eye), Gf.Vec3d(*TARGET), Gf.Vec3d(0, 0, 1))
        op.Set(view.GetInverse(), frame)
    stage.Save()
    manifest = render_stage(tmp / "stage.usda", tmp / "out", spp=1)
    return tmp, manifest


def test_keypoints_project_with_the_written_camera(ir_render):
    tmp, manifest = ir_render
    out = tmp / "out"
    [rec] = manifest["sensors"]
    assert rec["camera"] == "cam/camera.json"
    cam_file = json.loads((out / rec["camera"]).read_text())
    assert cam_file["distortion"] == [0.0] * 5 and (cam_file["width"], cam_file["height"]) == (W, H)
    assert [f["frame"] for f in cam_file["frames"]] == [0, 1]
    k = np.array(cam_file["K"])
    coco = json.loads((out / "coco.json").read_text())
    assert {img["humv_camera"] for img in coco["images"]} == {"cam/camera.json"}
    # the keypoints from the stage (not from objects.json), world = local + the Keys translate
    stage = Usd.Stage.Open(str(tmp / "stage.usda"))
    local = np.array(
        stage.GetPrimAtPath("/World/Humans/p1/Keys").GetAttribute(UA.COCO_KEYPOINTS_ATTR).Get(0), dtype=float
    )
    world = local + [0.0, 0.0, 0.9]
    seen = 0
    for frame, eye in ((0, EYE), (1, EYE1)):
        objects = json.loads((out / "cam" / f"{frame:04d}.objects.json").read_text())
        assert objects["camera"] == "cam/camera.json"
        [person] = [o for o in objects["objects"] if o["class"] == "person"]
        [pose] = [f for f in cam_file["frames"] if f["frame"] == frame]
        rot, t = np.array(pose["R"]), np.array(pose["t"])
        assert_allclose(pose["camera_origin_m"], eye, atol=1e-5)  # the stage's camera, independently
        assert_allclose(-rot.T @ t, eye, atol=1e-5)
        xc = world @ rot.T + t
        uv = (xc @ k.T)[:, :2] / xc[:, 2:]
        kp = np.array(person["keypoints"]).reshape(17, 3)
        labelled = kp[:, 2] > 0
        assert labelled.sum() >= 10
        assert np.abs(uv[labelled] - kp[labelled, :2]).max() < 0.5
        seen += labelled.sum()
        spec, ch = _oiio_channels(out / "cam" / f"{frame:04d}.exr")
        _header_agrees_with_camera_file(spec, cam_file, frame)
        assert spec.getattribute("humv:camera") == "cam/camera.json"
        ids = ch["label.instance_id"]
        assert ids.dtype == np.uint32 and set(np.unique(ids).tolist()) == {0, 1, 3}
        assert ch["label.class_id"].dtype == np.uint32
        assert spec.channelnames[spec.z_channel] == "Z"
        person_depth = ch["Z"][ids == 1]
        assert np.isfinite(person_depth).all() and 4.0 < np.median(person_depth) < 7.0
        assert (ch["Z"][ids == 0] == np.inf).all()
    assert seen >= 20
    # the frames differ: the camera moved
    assert cam_file["frames"][0]["t"] != cam_file["frames"][1]["t"]


def test_ir_file_opens_as_a_grey_image(ir_render):
    """R = G = B: the brightness temperature stretched as the PNG preview, 0..1 (not black)."""
    tmp, manifest = ir_render
    spec, ch = _oiio_channels(tmp / "out" / "cam" / "0000.exr")
    assert list(spec.channelnames[:3]) == ["R", "G", "B"]
    assert str(spec.channelformat(0)) == "half"
    bt = ch["IR.brightness_temperature"].astype(float)
    lo, hi = manifest["sensors"][0]["frames"][0]["preview_levels_k"]
    grey = np.where(np.isfinite(bt), np.clip((bt - lo) / (hi - lo), 0, 1), 0)
    for c in "RGB":
        assert_allclose(ch[c].astype(float), grey, atol=1e-3)
    assert ch["R"].max() == pytest.approx(1.0) and ch["R"].astype(float).mean() > 0.05  # not black
    chans = manifest["channels"]
    assert chans["instance_id"] == {
        "exr": "label.instance_id",
        "unit": chans["instance_id"]["unit"],
        "dtype": "uint32",
    }
    assert chans["depth"]["exr"] == "Z" and chans["R"]["dtype"] == "half"


def test_camera_file_states_a_zoom_per_frame():
    from humv_usd.geometry.camera import camera_file

    pose = CameraPose(np.zeros(3), np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0]), 40.0)
    wide = Camera.from_pose(pose, 64, 48)
    tele = Camera.from_pose(CameraPose(pose.origin, pose.forward, pose.up, 10.0), 64, 48)
    doc = camera_file("cam", [(0, wide), (1, wide), (2, tele)])
    assert "K" not in doc["frames"][0] and "K" not in doc["frames"][1]
    fx = 32 / np.tan(np.radians(5.0))
    assert_allclose(doc["frames"][2]["K"], [[fx, 0, 32], [0, fx, 24], [0, 0, 1]])
    assert_allclose(np.array(doc["K_integer_centres"]) - doc["K"], [[0, 0, -0.5], [0, 0, -0.5], [0, 0, 0]])
    # looking along +x with z up: OpenCV R rows are right (-y), down (-z), forward (+x)
    assert_allclose(doc["frames"][0]["R"], [[0, -1, 0], [0, 0, -1], [1, 0, 0]], atol=1e-12)


def test_preview_stretch_keeps_a_small_person_readable():
    """A warm person on 1 % of the pixels: the plain 1-99 % stretch saturates most of them; with
    the person's own percentiles kept (what the IR pass gives) at most 2 % sit at a level."""
    rng = np.random.default_rng(3)
    bt = 290.0 + 0.5 * rng.standard_normal((100, 100))
    person = np.zeros(bt.shape, dtype=bool)
    person[40:50, 45:55] = True
    bt[person] = 305.0 + 2.0 * rng.standard_normal(int(person.sum()))
    lo, hi = images.preview_levels(bt)
    assert np.mean(bt[person] >= hi) > 0.5  # saturated white
    lo, hi = images.preview_levels(bt, keep=person)
    clipped = (bt[person] >= hi) | (bt[person] <= lo)
    assert np.mean(clipped) <= 0.02 and lo <= np.percentile(bt, 1.0)
    assert images.preview_levels(bt, keep=np.zeros(bt.shape, dtype=bool)) == images.preview_levels(bt)
