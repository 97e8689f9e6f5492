"""How far ``UsdSkel.BakeSkinning`` puts each person's mesh from where the render puts it.

    .venv/bin/python tools/bake_skinning_distance.py out/walk/stage.usda

For every mesh under /World/Humans: the render's world points per frame
(:class:`humv_usd.render.scene_export.SceneMeshes`, UsdSkel skinning of what the stage holds),
then ``UsdSkel.BakeSkinning`` over the frame range on a flattened copy of the stage (it writes
into the edit target; the files are not touched), and the largest vertex distance [mm] per mesh
over the frames. Garments before clothing VERSION 2 (time-sampled rest points under a skel
binding) were 65 mm (leggings) and 80 mm (T-shirt) off on examples/walk.toml (10 frames); as a
point cache they agree exactly.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from pxr import Gf, Usd, UsdGeom, UsdSkel  # noqa: E402

from humv_usd.render.scene_export import SceneMeshes  # noqa: E402


def world(points, matrix) -> np.ndarray:
    m = np.asarray(matrix, dtype=float)
    return np.asarray(points, dtype=float) @ m[:3, :3] + m[3, :3]


def distances(stage_path) -> dict[str, float]:
    """{mesh path: max distance [m] between BakeSkinning's and the render's points}."""
    stage = Usd.Stage.Open(str(stage_path))
    meshes = SceneMeshes(stage)
    paths = [
        str(p.GetPath()) for p in stage.Traverse() if p.IsA(UsdGeom.Mesh) and "/Humans/" in str(p.GetPath())
    ]
    first, last = int(stage.GetStartTimeCode()), int(stage.GetEndTimeCode())
    render = {}
    for path in paths:
        for f in range(first, last + 1):
            pts, m = meshes.points(stage.GetPrimAtPath(path), path, Usd.TimeCode(f), UsdGeom.XformCache(f))
            render[path, f] = world(pts, m)
    baked = Usd.Stage.Open(stage.Flatten())
    UsdSkel.BakeSkinning(baked.Traverse(), Gf.Interval(first, last))
    out = {}
    for path in paths:
        prim = baked.GetPrimAtPath(path)
        out[path] = max(
            float(
                np.linalg.norm(
                    world(
                        UsdGeom.Mesh(prim).GetPointsAttr().Get(f),
                        UsdGeom.XformCache(f).GetLocalToWorldTransform(prim),
                    )
                    - render[path, f],
                    axis=1,
                ).max()
            )
            for f in range(first, last + 1)
        )
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("stage", help="a composed stage (OUT/stage.usda)")
    args = parser.parse_args(argv)
    for path, d in distances(args.stage).items():
        print(f"{path}: BakeSkinning vs render max {d * 1e3:.3f} mm")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
