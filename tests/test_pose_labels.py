"""Labels of people in the new poses (issue 29.6), end to end: a composed person lying on the
side / sitting / kneeling / stopping mid-stride (a motion sequence's blend), rendered, against an independent ray cast of the body skinned by
UsdSkel itself (``UsdSkel.BakeSkinning``) through pixel rays of the stage camera's own frustum
(``Gf.Frustum.ComputePickRay``), with trimesh/embree; keypoints and boxes of the same frame."""

from __future__ import annotations

import json

import numpy as np
import pytest
from pxr import Gf, Usd, UsdGeom, UsdSkel

from humv_usd.assets import makehuman_dir
from humv_usd.images import read_exr

pytestmark = [
    pytest.mark.extended,
    pytest.mark.skipif(not (makehuman_dir() / "rigs").is_dir(), reason="MakeHuman data not fetched"),
]

W, H = 64, 48


def _triangles(stage, frame):
    """World triangles of every mesh at ``frame`` and the mesh path of each."""
    tris, owner = [], []
    for prim in stage.Traverse(Usd.TraverseInstanceProxies()):
        if not prim.IsA(UsdGeom.Mesh) or UsdGeom.Imageable(prim).ComputeVisibility(frame) == "invisible":
            continue
        m = UsdGeom.Mesh(prim)
        xf = np.array(UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(frame), dtype=float)
        pts = m.GetPointsAttr().Get(frame)
        if pts is None:
            continue
        p = np.asarray(pts, dtype=float) @ xf[:3, :3] + xf[3, :3]
        counts = np.asarray(m.GetFaceVertexCountsAttr().Get(frame))
        idx = np.asarray(m.GetFaceVertexIndicesAttr().Get(frame))
        start = np.r_[0, np.cumsum(counts)[:-1]]
        for s, c in zip(start, counts):
            for k in range(1, c - 1):
                tris.append(p[[idx[s], idx[s + k], idx[s + k + 1]]])
                owner.append(str(prim.GetPath()))
    return np.array(tris), owner


@pytest.mark.parametrize("activity", ["lieSide", "sit", "kneel", "sequence"])
def test_pose_labels_agree_with_an_independent_ray_cast(raw, tmp_path, activity):
    import trimesh

    from humv_usd.human.poses import SEQUENCES
    from humv_usd.pipeline.compose import compose
    from humv_usd.pipeline.render import render_stage
    from humv_usd.scenario.load import validate

    fps = 2.0
    raw["general"]["fps"] = fps
    if activity == "sequence":  # a walk's stop blended into standing: t = 1 s is mid-blend
        raw["general"]["duration_s"] = 1.0
        raw["human"][0].pop("speed_m_s", None)
        raw["human"][0]["segment"] = [{"activity": "walk", "distance_m": 1.0}, {"activity": "stand"}]
    else:
        raw["general"]["duration_s"] = float(np.ceil(sum(d for _, d in SEQUENCES[activity]) + 1.0))
        raw["human"][0]["activity"] = activity
    raw["human"][0]["clothing"] = []
    raw["placement"][0]["heading_deg"] = 0.0
    raw["thermal"] = {"model": "fixed"}
    raw["atmosphere"]["model"] = "analytic"
    raw["sensor"] = [
        {
            "id": "cam",
            "band": "LWIR",
            "resolution": [W, H],
            "focal_length_mm": 4.0,
            "pixel_pitch_um": 17.0,
            "position_m": [2.5, -3.5, 1.6],
            "look_at_m": [0.0, 0.0, 0.4],
        }
    ]
    compose(validate(raw), tmp_path, yes=True)
    stage_path = tmp_path / "stage.usda"
    last = int(round(raw["general"]["duration_s"] * fps))
    render_stage(stage_path, tmp_path / "out", frames=[last], spp=1)
    channels = read_exr(tmp_path / "out" / "cam" / f"{last:04d}.exr")
    ids = np.asarray(channels["instance_id"]).astype(int)
    doc = json.loads((tmp_path / "out" / "cam" / f"{last:04d}.objects.json").read_text())
    [person] = [o for o in doc["objects"] if o["class"] == "person"]

    # independent: UsdSkel's own skinning, the camera's frustum, embree
    stage = Usd.Stage.Open(str(stage_path))
    stage.SetEditTarget(stage.GetSessionLayer())
    UsdSkel.BakeSkinning(stage.Traverse(), Gf.Interval(last, last))
    tris, owner = _triangles(stage, Usd.TimeCode(last))
    cam_prim = next(p for p in stage.Traverse() if p.IsA(UsdGeom.Camera))
    frustum = UsdGeom.Camera(cam_prim).GetCamera(Usd.TimeCode(last)).frustum
    origins, dirs = [], []
    for j in range(H):
        for i in range(W):
            ray = frustum.ComputePickRay(Gf.Vec2d((i + 0.5) / W * 2 - 1, 1 - (j + 0.5) / H * 2))
            origins.append(np.array(ray.startPoint))
            dirs.append(np.array(ray.direction))
    tm = trimesh.Trimesh(tris.reshape(-1, 3), np.arange(len(tris) * 3).reshape(-1, 3), process=False)
    _, ray_idx, tri_idx = tm.ray.intersects_location(np.array(origins), np.array(dirs), multiple_hits=False)
    is_person = np.zeros(W * H, bool)
    is_person[ray_idx] = [owner[t].startswith("/World/Humans/p1") for t in tri_idx]
    expect = is_person.reshape(H, W)
    got = ids == person["instance_id"]
    assert expect.sum() > 40, expect.sum()  # the person fills part of the image
    agree = (expect == got).mean()
    print(f"{activity}: person mask agreement {agree:.4f}, {expect.sum()} px")
    assert agree >= 0.99
    # the visible box is the mask's, the 3-D box stands on the ground and holds the keypoints
    rows, cols = np.nonzero(got)
    assert person["box_visible"] == [cols.min(), rows.min(), cols.max() + 1, rows.max() + 1]
    lo, hi = np.array(person["box_3d"]["min"]), np.array(person["box_3d"]["max"])
    assert -0.01 < lo[2] < 0.03
    skin_pts = tris[[o.startswith("/World/Humans/p1") for o in owner]].reshape(-1, 3)
    np.testing.assert_allclose(lo, skin_pts.min(0), atol=0.06)
    np.testing.assert_allclose(hi, skin_pts.max(0), atol=0.06)
