"""Render stage: closed-form radiometry (furnace, two temperatures), labels, outputs, bad input.

Stages are built by hand in tmp_path and author attributes by name (no API schema applied), as the
renderer must not depend on it. Images are small (64x48) to keep each test around a second.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import OpenImageIO as oiio
import pytest
from numpy.testing import assert_allclose
from pxr import Gf, Sdf, Usd, UsdGeom, UsdShade, Vt

from humv_usd import images as writers
from humv_usd.errors import InputError
from humv_usd.physics import planck
from humv_usd.pipeline.render import render_stage

W, H = 64, 48
LWIR = (8.0, 14.0)
MWIR = (3.0, 5.0)
ROOT = Path(__file__).resolve().parents[1]


# --- stage building ---------------------------------------------------------------------------


def new_stage(path, sky_k=300.0, start=0, end=0) -> Usd.Stage:
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    stage.SetStartTimeCode(start)
    stage.SetEndTimeCode(end)
    world = UsdGeom.Xform.Define(stage, "/World")
    stage.SetDefaultPrim(world.GetPrim())
    atmosphere = UsdGeom.Scope.Define(stage, "/World/Atmosphere").GetPrim()
    if sky_k is not None:
        attr = atmosphere.CreateAttribute("humv:atmosphere:skyTemperature", Sdf.ValueTypeNames.Float)
        if isinstance(sky_k, dict):
            for frame, value in sky_k.items():
                attr.Set(float(value), frame)
        else:
            attr.Set(float(sky_k))
    UsdGeom.Scope.Define(stage, "/World/Materials")
    UsdGeom.Scope.Define(stage, "/World/Scene")
    UsdGeom.Scope.Define(stage, "/World/Sensors")
    return stage


def add_material(stage, name, emissivity, wavelengths=(1.0, 20.0)) -> UsdShade.Material:
    material = UsdShade.Material.Define(stage, f"/World/Materials/{name}")
    prim = material.GetPrim()
    eps = np.broadcast_to(np.asarray(emissivity, dtype=float), (len(wavelengths),))
    prim.CreateAttribute("humv:material:wavelengths", Sdf.ValueTypeNames.FloatArray).Set(
        Vt.FloatArray(list(wavelengths))
    )
    prim.CreateAttribute("humv:material:emissivity", Sdf.ValueTypeNames.FloatArray).Set(
        Vt.FloatArray(eps.tolist())
    )
    return material


def add_mesh(stage, path, points, counts, indices, material=None, temperature_k=None, instance_id=None):
    mesh = UsdGeom.Mesh.Define(stage, path)
    mesh.CreatePointsAttr(Vt.Vec3fArray([Gf.Vec3f(*map(float, p)) for p in points]))
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray([int(c) for c in counts]))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray([int(i) for i in indices]))
    prim = mesh.GetPrim()
    if material is not None:
        UsdShade.MaterialBindingAPI.Apply(prim).Bind(material)
    if temperature_k is not None:
        primvar = UsdGeom.PrimvarsAPI(prim).CreatePrimvar(
            "humv:thermal:temperature", Sdf.ValueTypeNames.FloatArray, UsdGeom.Tokens.uniform
        )
        samples = (
            temperature_k if isinstance(temperature_k, dict) else {Usd.TimeCode.Default(): temperature_k}
        )
        for time, values in samples.items():
            values = (
                np.broadcast_to(np.asarray(values, dtype=float), (len(counts),))
                if np.ndim(values) == 0
                else values
            )
            primvar.Set(Vt.FloatArray([float(v) for v in values]), time)
    if instance_id is not None:
        prim.CreateAttribute("humv:label:instanceId", Sdf.ValueTypeNames.Int).Set(int(instance_id))
    return mesh


def quad(corners):
    """A one-face mesh from four corners (counter-clockwise seen from the front)."""
    return corners, [4], [0, 1, 2, 3]


def rect_z(x0, x1, y0, y1, z=0.0):
    """Horizontal rectangle facing +Z."""
    return quad([(x0, y0, z), (x1, y0, z), (x1, y1, z), (x0, y1, z)])


def rect_y(x0, x1, z0, z1, y):
    """Vertical rectangle at y facing -Y (towards a camera at smaller y)."""
    return quad([(x0, y, z0), (x1, y, z0), (x1, y, z1), (x0, y, z1)])


def box(center, size):
    """Closed axis-aligned box, outward-facing quads (split into 2x2 faces each: 24 faces)."""
    cx, cy, cz = center
    h = size / 2.0
    pts, counts, idx = [], [], []

    def face(origin, du, dv):
        # 2x2 grid of quads spanning origin + [0,1]du + [0,1]dv, counter-clockwise for du x dv
        base = len(pts)
        for j in range(3):
            for i in range(3):
                pts.append(tuple(np.asarray(origin) + 0.5 * i * np.asarray(du) + 0.5 * j * np.asarray(dv)))
        for j in range(2):
            for i in range(2):
                a = base + j * 3 + i
                counts.append(4)
                idx.extend([a, a + 1, a + 4, a + 3])

    s = 2 * h
    x0, y0, z0 = cx - h, cy - h, cz - h
    face((x0, y0, z0 + s), (s, 0, 0), (0, s, 0))  # top, normal +z
    face((x0, y0 + s, z0), (s, 0, 0), (0, -s, 0))  # bottom, normal -z
    face((x0, y0, z0), (s, 0, 0), (0, 0, s))  # front y0, normal -y
    face((x0 + s, y0 + s, z0), (-s, 0, 0), (0, 0, s))  # back, normal +y
    face((x0, y0 + s, z0), (0, -s, 0), (0, 0, s))  # left x0, normal -x
    face((x0 + s, y0, z0), (0, s, 0), (0, 0, s))  # right, normal +x
    return pts, counts, idx


def add_camera(
    stage,
    name,
    eye,
    target,
    fov_x_deg=40.0,
    resolution=(W, H),
    band=LWIR,
    band_token="LWIR",
    up=(0, 0, 1),
    netd=None,
):
    cam = UsdGeom.Camera.Define(stage, f"/World/Sensors/{name}")
    view = Gf.Matrix4d().SetLookAt(Gf.Vec3d(*eye), Gf.Vec3d(*target), Gf.Vec3d(*up))
    cam.AddTransformOp().Set(view.GetInverse())
    focal = 0.25
    h_ap = 2 * focal * np.tan(np.radians(fov_x_deg) / 2)
    cam.CreateFocalLengthAttr(focal)
    cam.CreateHorizontalApertureAttr(float(h_ap))
    cam.CreateVerticalApertureAttr(float(h_ap * resolution[1] / resolution[0]))
    prim = cam.GetPrim()
    prim.CreateAttribute("humv:sensor:band", Sdf.ValueTypeNames.Token).Set(band_token)
    prim.CreateAttribute("humv:sensor:wavelengthRange", Sdf.ValueTypeNames.Float2).Set(Gf.Vec2f(*band))
    prim.CreateAttribute("humv:sensor:resolution", Sdf.ValueTypeNames.Int2).Set(Gf.Vec2i(*resolution))
    if netd is not None:
        prim.CreateAttribute("humv:sensor:netd", Sdf.ValueTypeNames.Float).Set(float(netd))
    return cam


def read_exr(path):
    """(ImageSpec, channels by logical name as float32); uint32 ids come back exact."""
    ch, spec = writers.read_exr(path, with_spec=True)
    return spec, {name: np.asarray(v).astype(np.float32) for name, v in ch.items()}


def within_noise(radiance, stderr, expected, k=5.0, rel=1e-4):
    """|L - expected| <= k sigma + rel expected per pixel.

    sigma is the pixel's standard error, but at least half the image's RMS one: with a few spp the
    per-pixel estimate is itself noisy (the samples are far from normal, e.g. with Russian
    roulette) and now and then much too small.
    """
    pooled = np.sqrt(np.mean(np.square(stderr)))
    return np.abs(radiance - expected) <= k * np.maximum(stderr, 0.5 * pooled) + rel * np.abs(expected)


# --- closed-form radiometry -------------------------------------------------------------------


@pytest.mark.parametrize("emissivity", [0.1, 0.5, 0.95])
def test_furnace_isothermal_scene_is_blackbody(tmp_path, emissivity):
    t = 300.0
    stage = new_stage(tmp_path / "stage.usda", sky_k=t)
    mat = add_material(stage, "gray", emissivity)
    add_mesh(
        stage, "/World/Scene/ground", *rect_z(-30, 30, -30, 30), material=mat, temperature_k=t, instance_id=1
    )
    add_mesh(
        stage, "/World/Scene/wall", *box((0.0, 0.0, 1.0), 2.0), material=mat, temperature_k=t, instance_id=2
    )
    add_camera(stage, "lwir", eye=(3.0, -6.0, 3.0), target=(0.0, 0.0, 0.8), fov_x_deg=50)
    stage.Save()
    manifest = render_stage(tmp_path / "stage.usda", tmp_path / "out", spp=32)
    _, ch = read_exr(tmp_path / "out" / "lwir" / "0000.exr")
    b = planck.band_radiance(t, LWIR)
    # the view holds ground, box and sky
    assert {0, 1, 2} <= set(np.unique(ch["instance_id"]).astype(int).tolist())
    ok = within_noise(ch["radiance"], ch["radiance_stderr"], b)
    assert ok.all(), f"{(~ok).sum()} pixels off; worst {np.abs(ch['radiance'] - b).max() / b:.2e} relative"
    assert abs(ch["radiance"].mean() / b - 1) < 1e-3
    assert abs(np.median(ch["brightness_temperature"]) - t) < 0.05
    err = manifest["monte_carlo_error"]
    assert_allclose(err["radiance_stderr_max"], ch["radiance_stderr"].max(), rtol=1e-6)
    assert_allclose(err["radiance_stderr_mean"], ch["radiance_stderr"].astype(float).mean(), rtol=1e-5)


@pytest.mark.parametrize(
    "eps,t1,t2,band",
    [
        (0.9, 310.0, 250.0, LWIR),
        (0.3, 350.0, 280.0, LWIR),
        (0.6, 310.0, 290.0, MWIR),
    ],
)
def test_plate_under_sky(tmp_path, eps, t1, t2, band):
    stage = new_stage(tmp_path / "stage.usda", sky_k=t2)
    mat = add_material(stage, "plate", eps)
    add_mesh(
        stage,
        "/World/Scene/plate",
        *rect_z(-100, 100, -100, 100),
        material=mat,
        temperature_k=t1,
        instance_id=5,
    )
    add_camera(
        stage,
        "ir",
        eye=(0.0, 0.0, 10.0),
        target=(0.0, 0.0, 0.0),
        fov_x_deg=30,
        up=(0, 1, 0),
        band=band,
        band_token="LWIR" if band == LWIR else "MWIR",
    )
    stage.Save()
    # one gray band, 16 samples per pixel: the 5-sigma per-pixel check needs the per-pixel error
    # estimate of 16 samples (sub-bands: tests/test_render_radiometry.py)
    render_stage(tmp_path / "stage.usda", tmp_path / "out", spp=16, subbands=1)
    _, ch = read_exr(tmp_path / "out" / "ir" / "0000.exr")
    expected = eps * planck.band_radiance(t1, band) + (1 - eps) * planck.band_radiance(t2, band)
    assert (ch["instance_id"] == 5).all()
    ok = within_noise(ch["radiance"], ch["radiance_stderr"], expected)
    assert ok.all(), f"{(~ok).sum()} pixels off"
    assert abs(ch["radiance"].mean() / expected - 1) < 1e-3
    # and not the answer of a wrong model (plate emission only, or a blackbody plate)
    assert abs(ch["radiance"].mean() / (eps * planck.band_radiance(t1, band)) - 1) > 1e-2


# --- labels -----------------------------------------------------------------------------------


def _pinhole_rays(eye, target, up, fov_x_deg, w, h, dx=0.0, dy=0.0):
    """Unit ray directions through pixel centres (+offset in pixels), row 0 at the top."""
    eye, target, up = (np.asarray(v, dtype=float) for v in (eye, target, up))
    fwd = target - eye
    fwd /= np.linalg.norm(fwd)
    right = np.cross(fwd, up)
    right /= np.linalg.norm(right)
    cam_up = np.cross(right, fwd)
    tx = np.tan(np.radians(fov_x_deg) / 2)
    ty = tx * h / w
    u = ((np.arange(w) + 0.5 + dx) / w * 2 - 1) * tx
    v = (1 - (np.arange(h) + 0.5 + dy) / h * 2) * ty
    uu, vv = np.meshgrid(u, v)
    d = fwd + uu[..., None] * right + vv[..., None] * cam_up
    return d / np.linalg.norm(d, axis=-1, keepdims=True), fwd


def _closest_hit(eye, dirs, rects):
    """Closed-form ray casting against axis-aligned rectangles (axis, value, bounds, id)."""
    t_best = np.full(dirs.shape[:2], np.inf)
    id_best = np.zeros(dirs.shape[:2], dtype=int)
    for axis, value, (a0, a1, b0, b1), ident in rects:
        others = [i for i in range(3) if i != axis]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (value - eye[axis]) / dirs[..., axis]
        p = eye + t[..., None] * dirs
        inside = (
            (t > 0)
            & (p[..., others[0]] >= a0)
            & (p[..., others[0]] <= a1)
            & (p[..., others[1]] >= b0)
            & (p[..., others[1]] <= b1)
        )
        better = inside & (t < t_best)
        t_best = np.where(better, t, t_best)
        id_best = np.where(better, ident, id_best)
    return t_best, id_best


def test_depth_and_instance_labels(tmp_path):
    stage = new_stage(tmp_path / "stage.usda", sky_k=260.0)
    mat = add_material(stage, "m", 0.9)
    # ground labelled through its parent Xform (nearest labelled ancestor)
    UsdGeom.Xform.Define(stage, "/World/Scene/terrain").GetPrim().CreateAttribute(
        "humv:label:instanceId", Sdf.ValueTypeNames.Int
    ).Set(11)
    add_mesh(
        stage, "/World/Scene/terrain/ground", *rect_z(-500, 500, -500, 500), material=mat, temperature_k=290.0
    )
    # a wall on the right half of the view, facing the camera
    add_mesh(
        stage,
        "/World/Scene/wall",
        *rect_y(1.0, 6.0, 0.0, 4.0, y=12.0),
        material=mat,
        temperature_k=300.0,
        instance_id=42,
    )
    eye, target, up, fov = (0.0, 0.0, 2.0), (0.0, 10.0, 1.2), (0, 0, 1), 60.0
    add_camera(stage, "cam", eye=eye, target=target, fov_x_deg=fov, up=up)
    stage.Save()
    render_stage(tmp_path / "stage.usda", tmp_path / "out", spp=1)
    _, ch = read_exr(tmp_path / "out" / "cam" / "0000.exr")

    rects = [(2, 0.0, (-500, 500, -500, 500), 11), (1, 12.0, (1.0, 6.0, 0.0, 4.0), 42)]
    eye_a = np.asarray(eye, dtype=float)
    dirs, fwd = _pinhole_rays(eye, target, up, fov, W, H)
    t, ident = _closest_hit(eye_a, dirs, rects)
    depth = t * (dirs @ fwd)
    # pixels whose centre ray lies within 0.01 px of an edge are ambiguous; leave them out
    same = np.ones_like(ident, dtype=bool)
    for dx, dy in ((0.01, 0), (-0.01, 0), (0, 0.01), (0, -0.01)):
        same &= _closest_hit(eye_a, _pinhole_rays(eye, target, up, fov, W, H, dx, dy)[0], rects)[1] == ident
    assert same.sum() > 0.95 * W * H
    assert {0, 11, 42} <= set(np.unique(ident[same]).tolist())
    assert_allclose(ch["instance_id"][same], ident[same])
    sky = same & (ident == 0)
    assert np.isposinf(ch["depth"][sky]).all()
    hit = same & (ident > 0)
    # OptiX (the CUDA backend) reports hit distances to 2.85e-5 relative (measured on an H100),
    # Embree to 2e-5
    from humv_usd import mode

    assert_allclose(ch["depth"][hit], depth[hit], rtol=5e-5 if mode.backend() == "cuda" else 2e-5)
    # the wall is in the right half of the image, the sky at the top
    cols = np.nonzero(ch["instance_id"] == 42)[1]
    assert cols.min() >= W // 2
    assert (ch["instance_id"][0] == 0).all()


def test_depth_of_a_perpendicular_plane_is_constant(tmp_path):
    # optical-axis distance, not Euclidean distance: the same for every pixel of the plane
    stage = new_stage(tmp_path / "stage.usda")
    mat = add_material(stage, "m", 1.0)
    add_mesh(
        stage,
        "/World/Scene/plane",
        *rect_y(-50, 50, -50, 50, y=7.5),
        material=mat,
        temperature_k=300.0,
        instance_id=3,
    )
    add_camera(stage, "cam", eye=(0.0, 0.0, 0.0), target=(0.0, 1.0, 0.0), fov_x_deg=70)
    stage.Save()
    render_stage(tmp_path / "stage.usda", tmp_path / "out", spp=4)
    _, ch = read_exr(tmp_path / "out" / "cam" / "0000.exr")
    assert_allclose(ch["depth"], 7.5, rtol=1e-5)
    assert (ch["instance_id"] == 3).all()
    # a blackbody plate: every pixel is B(T) (no reflection, no noise); the reported error is at
    # most the float32 resolution of the moments (ir.MOMENT_RESOLUTION)
    b = planck.band_radiance(300.0, LWIR)
    assert_allclose(ch["radiance"], b, rtol=1e-5)
    assert (ch["radiance_stderr"] <= 3e-4 * b).all()


# --- outputs ----------------------------------------------------------------------------------


def _small_scene(path, start=0, end=1, temperature=305.0):
    stage = new_stage(path, sky_k=270.0, start=start, end=end)
    mat = add_material(stage, "m", 0.8)
    add_mesh(
        stage,
        "/World/Scene/ground",
        *rect_z(-20, 20, -20, 20),
        material=mat,
        temperature_k=temperature,
        instance_id=1,
    )
    add_mesh(
        stage,
        "/World/Scene/box",
        *box((0.0, 0.0, 0.5), 1.0),
        material=mat,
        temperature_k=310.0,
        instance_id=2,
    )
    add_camera(stage, "lwir", eye=(2.0, -5.0, 2.0), target=(0.0, 0.0, 0.5))
    cam = add_camera(
        stage, "eo", eye=(2.0, -5.0, 2.0), target=(0.0, 0.0, 0.5), band=(0.4, 0.7), band_token="EO"
    )
    assert cam
    return stage


def test_outputs_manifest_and_reproducibility(tmp_path):
    stage = _small_scene(tmp_path / "stage.usda")
    stage.Save()
    out = tmp_path / "out"
    manifest = render_stage(tmp_path / "stage.usda", out, spp=8, seed=7)

    exr = out / "lwir" / "0001.exr"
    spec, ch = read_exr(exr)
    labels = set(manifest["ground_truth"]["channels"])  # ground-truth channels: tests/test_groundtruth.py
    chain = {"counts"} if manifest["sensor_chain"].startswith("ran") else set()  # sensor chain raw counts
    assert set(ch) - labels - chain == {
        "radiance",
        "brightness_temperature",
        "radiance_stderr",
        "depth",
        "instance_id",
        "R",  # display-only grey preview (issue 12)
        "G",
        "B",
    }
    assert len(spec.channelnames) == 8 + len(labels) + len(chain)
    # stored types as the manifest states them: uint32 ids, half preview, float32 data (issue 12)
    stored = {writers.logical_name(n): str(spec.channelformat(i)) for i, n in enumerate(spec.channelnames)}
    dtypes = {"uint32": "uint", "half": "half", "float32": "float"}
    assert stored == {
        name: dtypes[manifest["channels"][name]["dtype"]] if name in manifest["channels"] else "float"
        for name in stored
    }
    assert (spec.width, spec.height) == (W, H)
    assert_allclose(
        ch["brightness_temperature"], planck.brightness_temperature(ch["radiance"], LWIR), atol=1e-3
    )
    assert (ch["radiance_stderr"] >= 0).all() and ch["radiance_stderr"].max() > 0

    png = oiio.ImageInput.open(str(out / "lwir" / "0001.png"))
    assert png.spec().nchannels == 1 and str(png.spec().format) == "uint8"
    png.close()
    assert not any(p.name.startswith(".") for p in (out / "lwir").iterdir())  # no temp files left

    on_disk = json.loads((out / "manifest.json").read_text())
    assert on_disk == json.loads(json.dumps(manifest))
    assert set(on_disk["versions"]) == {"humv_usd", "mitsuba", "drjit", "usd", "numpy", "OpenImageIO"}
    assert on_disk["mitsuba_variant"] in ("cuda_ad_mono", "llvm_ad_mono", "scalar_rgb")
    assert on_disk["settings"]["spp"] == 8 and on_disk["settings"]["seed"] == 7
    assert on_disk["settings"]["frames"] == [0, 1] and on_disk["settings"]["max_depth"] == -1
    for key in ("load_export", "render", "labels", "write", "total"):
        assert on_disk["timings_s"][key] >= 0
    [sensor] = on_disk["sensors"]
    assert sensor["name"] == "lwir" and [f["frame"] for f in sensor["frames"]] == [0, 1]
    assert set(sensor["timings_s"]) == {"load_export", "render", "labels", "write", "total"}
    for err in [
        on_disk["monte_carlo_error"],
        sensor["monte_carlo_error"],
        sensor["frames"][1]["monte_carlo_error"],
    ]:
        assert 0 < err["radiance_stderr_mean"] <= err["radiance_stderr_max"]
        assert 0 < err["temperature_stderr_mean_k"] <= err["temperature_stderr_max_k"]
    assert "percentile" in on_disk["preview"]["stretch"]
    [skipped] = on_disk["skipped_sensors"]
    assert (
        skipped["name"] == "eo" and "no visible illumination" in skipped["reason"]
    )  # no atmosphere tables here
    assert not (out / "eo").exists()

    # same seed: the same radiance; another seed: different noise
    render_stage(tmp_path / "stage.usda", tmp_path / "again", frames=[1], spp=8, seed=7, sensors=["lwir"])
    _, ch2 = read_exr(tmp_path / "again" / "lwir" / "0001.exr")
    assert np.array_equal(ch["radiance"], ch2["radiance"])
    render_stage(tmp_path / "stage.usda", tmp_path / "other", frames=[1], spp=8, seed=8, sensors=["lwir"])
    _, ch3 = read_exr(tmp_path / "other" / "lwir" / "0001.exr")
    assert not np.array_equal(ch["radiance"], ch3["radiance"])


def test_time_sampled_temperature_updates_without_rebuild(tmp_path):
    stage = new_stage(tmp_path / "stage.usda", sky_k=250.0, start=0, end=1)
    mat = add_material(stage, "black", 1.0)
    add_mesh(
        stage,
        "/World/Scene/plate",
        *rect_z(-100, 100, -100, 100),
        material=mat,
        temperature_k={0: [300.0], 1: [320.0]},
        instance_id=1,
    )
    add_camera(stage, "ir", eye=(0.0, 0.0, 10.0), target=(0.0, 0.0, 0.0), up=(0, 1, 0))
    stage.Save()
    manifest = render_stage(tmp_path / "stage.usda", tmp_path / "out", spp=4)
    assert manifest["scene_builds"] == 1
    _, f0 = read_exr(tmp_path / "out" / "ir" / "0000.exr")
    _, f1 = read_exr(tmp_path / "out" / "ir" / "0001.exr")
    assert_allclose(f0["radiance"], planck.band_radiance(300.0, LWIR), rtol=1e-5)
    assert_allclose(f1["radiance"], planck.band_radiance(320.0, LWIR), rtol=1e-5)
    assert_allclose(f1["brightness_temperature"], 320.0, atol=1e-3)


def test_moving_mesh_updates_vertices(tmp_path):
    stage = new_stage(tmp_path / "stage.usda", sky_k=250.0, start=0, end=1)
    mat = add_material(stage, "black", 1.0)
    mesh = add_mesh(
        stage,
        "/World/Scene/plate",
        *rect_y(-100, 100, -100, 100, y=5.0),
        material=mat,
        temperature_k=300.0,
        instance_id=1,
    )
    mesh.AddTranslateOp().Set(Gf.Vec3d(0, 0, 0), 0)
    mesh.GetPrim().GetAttribute("xformOp:translate").Set(Gf.Vec3d(0, 4.0, 0), 1)
    add_camera(stage, "ir", eye=(0.0, 0.0, 0.0), target=(0.0, 1.0, 0.0))
    stage.Save()
    manifest = render_stage(tmp_path / "stage.usda", tmp_path / "out", spp=1)
    assert manifest["scene_builds"] == 1
    _, f0 = read_exr(tmp_path / "out" / "ir" / "0000.exr")
    _, f1 = read_exr(tmp_path / "out" / "ir" / "0001.exr")
    assert_allclose(f0["depth"], 5.0, rtol=1e-5)
    assert_allclose(f1["depth"], 9.0, rtol=1e-5)


# --- bad input --------------------------------------------------------------------------------


def _plate_stage(path, **mesh_kwargs):
    stage = new_stage(path)
    mat = add_material(stage, "m", 0.9)
    kwargs = {"material": mat, "temperature_k": 300.0, **mesh_kwargs}
    add_mesh(stage, "/World/Scene/plate", *rect_z(-10, 10, -10, 10), **kwargs)
    add_camera(stage, "ir", eye=(0.0, 0.0, 10.0), target=(0.0, 0.0, 0.0), up=(0, 1, 0))
    return stage


def test_missing_temperature_primvar(tmp_path):
    _plate_stage(tmp_path / "s.usda", temperature_k=None).Save()
    with pytest.raises(InputError, match=r"/World/Scene/plate\.primvars:humv:thermal:temperature"):
        render_stage(tmp_path / "s.usda", tmp_path / "out")


def test_wrong_temperature_length(tmp_path):
    _plate_stage(tmp_path / "s.usda", temperature_k=[300.0, 301.0, 302.0]).Save()
    with pytest.raises(
        InputError, match=r"/World/Scene/plate\.primvars:humv:thermal:temperature.*3 values.*expected 1 "
    ):
        render_stage(tmp_path / "s.usda", tmp_path / "out")


@pytest.mark.parametrize("bad", [float("nan"), 0.5, 6000.0])
def test_temperature_out_of_range(tmp_path, bad):
    _plate_stage(tmp_path / "s.usda", temperature_k=bad).Save()
    with pytest.raises(InputError, match=r"/World/Scene/plate\.primvars:humv:thermal:temperature.*1-5000 K"):
        render_stage(tmp_path / "s.usda", tmp_path / "out")


def test_missing_sky_temperature(tmp_path):
    stage = _plate_stage(tmp_path / "s.usda")
    stage.GetPrimAtPath("/World/Atmosphere").RemoveProperty("humv:atmosphere:skyTemperature")
    stage.Save()
    with pytest.raises(InputError, match=r"/World/Atmosphere\.humv:atmosphere:skyTemperature"):
        render_stage(tmp_path / "s.usda", tmp_path / "out")


def test_missing_material(tmp_path):
    _plate_stage(tmp_path / "s.usda", material=None).Save()
    with pytest.raises(InputError, match=r"/World/Scene/plate\.material:binding"):
        render_stage(tmp_path / "s.usda", tmp_path / "out")


def test_bad_frames_and_settings(tmp_path):
    _plate_stage(tmp_path / "s.usda").Save()
    with pytest.raises(InputError, match=r"frames = 5"):
        render_stage(tmp_path / "s.usda", tmp_path / "out", frames=[5])
    with pytest.raises(InputError, match=r"spp"):
        render_stage(tmp_path / "s.usda", tmp_path / "out", spp=0)
    with pytest.raises(InputError, match=r"sensors = 'nope'"):
        render_stage(tmp_path / "s.usda", tmp_path / "out", sensors=["nope"])
    assert not (tmp_path / "out" / "manifest.json").exists()


# --- fallback variant -------------------------------------------------------------------------


@pytest.mark.slow
def test_scalar_rgb_fallback_keeps_radiometry(tmp_path):
    """The scalar fallback (no LLVM 19) renders the two-temperature plate right, in a subprocess."""
    eps, t1, t2 = 0.7, 320.0, 260.0
    stage = new_stage(tmp_path / "stage.usda", sky_k=t2)
    mat = add_material(stage, "plate", eps)
    add_mesh(
        stage,
        "/World/Scene/plate",
        *rect_z(-100, 100, -100, 100),
        material=mat,
        temperature_k=t1,
        instance_id=5,
    )
    add_camera(stage, "ir", eye=(0.0, 0.0, 10.0), target=(0.0, 0.0, 0.0), up=(0, 1, 0), resolution=(16, 12))
    stage.Save()
    code = (
        "import json, sys; from humv_usd.pipeline.render import render_stage; "
        "m = render_stage(sys.argv[1], sys.argv[2], spp=16); print(json.dumps(m['mitsuba_variant']))"
    )
    # the project first, then whatever path the caller set up (a GPU machine's carried packages)
    path = os.pathsep.join(p for p in (str(ROOT), os.environ.get("PYTHONPATH", "")) if p)
    env = {**os.environ, "HUMV_USD_MITSUBA_VARIANT": "scalar_rgb", "PYTHONPATH": path}
    run = subprocess.run(
        [sys.executable, "-c", code, str(tmp_path / "stage.usda"), str(tmp_path / "out")],
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert run.returncode == 0, run.stderr[-2000:]
    assert json.loads(run.stdout.strip().splitlines()[-1]) == "scalar_rgb"
    _, ch = read_exr(tmp_path / "out" / "ir" / "0000.exr")
    expected = eps * planck.band_radiance(t1, LWIR) + (1 - eps) * planck.band_radiance(t2, LWIR)
    assert (ch["instance_id"] == 5).all()
    assert within_noise(ch["radiance"], ch["radiance_stderr"], expected).all()
    assert abs(ch["radiance"].mean() / expected - 1) < 2e-3


# --- materials, winding, response -------------------------------------------------------------


def test_geom_subset_materials_and_left_handed_winding(tmp_path):
    t, t_sky = 320.0, 260.0
    stage = new_stage(tmp_path / "stage.usda", sky_k=t_sky)
    black = add_material(stage, "black", 1.0)
    gray = add_material(stage, "gray", 0.5)
    # two faces side by side, authored clockwise seen from above (leftHanded): x<0 black, x>0 gray
    pts = [(-50, -50, 0), (0, -50, 0), (50, -50, 0), (-50, 50, 0), (0, 50, 0), (50, 50, 0)]
    mesh = add_mesh(
        stage,
        "/World/Scene/plate",
        pts,
        [4, 4],
        [0, 3, 4, 1, 1, 4, 5, 2],
        material=black,
        temperature_k=t,
        instance_id=1,
    )
    mesh.CreateOrientationAttr(UsdGeom.Tokens.leftHanded)
    binding = UsdShade.MaterialBindingAPI(mesh.GetPrim())
    subset = binding.CreateMaterialBindSubset("right", Vt.IntArray([1]))
    UsdShade.MaterialBindingAPI.Apply(subset.GetPrim()).Bind(gray)
    add_camera(stage, "ir", eye=(0.0, 0.0, 10.0), target=(0.0, 0.0, 0.0), up=(0, 1, 0), fov_x_deg=60)
    stage.Save()
    render_stage(tmp_path / "stage.usda", tmp_path / "out", spp=16)
    _, ch = read_exr(tmp_path / "out" / "ir" / "0000.exr")
    b, b_sky = planck.band_radiance(t, LWIR), planck.band_radiance(t_sky, LWIR)
    left, right = ch["radiance"][:, : W // 2 - 1], ch["radiance"][:, W // 2 + 1 :]
    assert_allclose(left, b, rtol=1e-5)  # front side seen: leftHanded winding was honoured
    assert abs(right.mean() / (0.5 * b + 0.5 * b_sky) - 1) < 2e-3


def test_sensor_response_weights_the_band(tmp_path):
    stage = new_stage(tmp_path / "stage.usda", sky_k=250.0)
    mat = add_material(stage, "black", 1.0)
    add_mesh(stage, "/World/Scene/plate", *rect_z(-100, 100, -100, 100), material=mat, temperature_k=310.0)
    cam = add_camera(
        stage, "ir", eye=(0.0, 0.0, 10.0), target=(0.0, 0.0, 0.0), up=(0, 1, 0), band=(7.5, 14.5)
    )
    wl, r = [7.5, 8.0, 12.0, 14.5], [0.0, 1.0, 0.8, 0.0]
    cam.GetPrim().CreateAttribute("humv:sensor:responseWavelengths", Sdf.ValueTypeNames.FloatArray).Set(
        Vt.FloatArray(wl)
    )
    cam.GetPrim().CreateAttribute("humv:sensor:response", Sdf.ValueTypeNames.FloatArray).Set(Vt.FloatArray(r))
    stage.Save()
    manifest = render_stage(tmp_path / "stage.usda", tmp_path / "out", spp=2)
    _, ch = read_exr(tmp_path / "out" / "ir" / "0000.exr")
    response = (np.array(wl), np.array(r))
    assert_allclose(ch["radiance"], planck.band_radiance(310.0, (7.5, 14.5), response), rtol=1e-5)
    assert_allclose(ch["brightness_temperature"], 310.0, atol=1e-3)
    assert_allclose(manifest["sensors"][0]["response"]["values"], r, rtol=1e-7)


# --- variant choice ---------------------------------------------------------------------------


def test_variant_choice_without_llvm19(monkeypatch):
    from humv_usd import mode

    monkeypatch.delenv("DRJIT_LIBLLVM_PATH", raising=False)
    monkeypatch.delenv(mode.VARIANT_ENV, raising=False)
    monkeypatch.delenv(mode.BACKEND_ENV, raising=False)
    monkeypatch.delitem(sys.modules, "drjit", raising=False)
    monkeypatch.setattr(mode, "LLVM19_GLOBS", ("/nonexistent/libLLVM.so.19*",))
    monkeypatch.setattr(mode, "CUDA_GLOBS", ("/nonexistent/libcuda.so*",))
    variant, reason = mode._choose_variant()
    assert variant == "scalar_rgb" and "LLVM 19" in reason
    assert "DRJIT_LIBLLVM_PATH" not in os.environ


def test_variant_choice_points_drjit_at_llvm19(monkeypatch, tmp_path):
    from humv_usd import mode

    fake = tmp_path / "libLLVM.so.19.1"
    fake.write_bytes(b"")
    monkeypatch.delenv("DRJIT_LIBLLVM_PATH", raising=False)
    monkeypatch.delenv(mode.VARIANT_ENV, raising=False)
    monkeypatch.delenv(mode.BACKEND_ENV, raising=False)
    monkeypatch.delitem(sys.modules, "drjit", raising=False)
    monkeypatch.setattr(mode, "LLVM19_GLOBS", (str(tmp_path / "libLLVM.so.19*"),))
    monkeypatch.setattr(mode, "CUDA_GLOBS", ("/nonexistent/libcuda.so*",))
    variant, _ = mode._choose_variant()
    assert variant == "llvm_ad_mono" and os.environ["DRJIT_LIBLLVM_PATH"] == str(fake)
    monkeypatch.setenv(mode.VARIANT_ENV, "cuda_ad_rgb")
    with pytest.raises(ValueError, match="HUMV_USD_MITSUBA_VARIANT"):
        mode._choose_variant()


def test_double_sided_mesh_emits_and_reflects_on_its_back(tmp_path):
    """A doubleSided surface (garments, open shells) seen from behind is the same plate as seen
    from the front; a one-sided one is black from behind (Mitsuba area lights are one-sided)."""
    eps, t1, t2 = 0.8, 310.0, 260.0
    expected = eps * planck.band_radiance(t1, LWIR) + (1 - eps) * planck.band_radiance(t2, LWIR)
    for double, out in ((True, "two"), (False, "one")):
        stage = new_stage(tmp_path / f"{out}.usda", sky_k=t2)
        mat = add_material(stage, "plate", eps)
        add_mesh(
            stage,
            "/World/Scene/plate",
            *rect_z(-100, 100, -100, 100),
            material=mat,
            temperature_k=t1,
            instance_id=5,
        )
        UsdGeom.Mesh(stage.GetPrimAtPath("/World/Scene/plate")).CreateDoubleSidedAttr(double)
        add_camera(stage, "ir", eye=(0.0, 0.0, -10.0), target=(0.0, 0.0, 0.0), fov_x_deg=30, up=(0, 1, 0))
        stage.Save()
        render_stage(tmp_path / f"{out}.usda", tmp_path / out, spp=8)
        _, ch = read_exr(tmp_path / out / "ir" / "0000.exr")
        if double:
            assert within_noise(ch["radiance"], ch["radiance_stderr"], expected).all()
        else:
            assert np.all(ch["radiance"] == 0.0)
