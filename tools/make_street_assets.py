"""Make the 3D assets of examples/street.toml, in three formats a DCC would hand over.

* ``vehicle.glb`` (glTF binary, Y-up metres by the glTF spec; trimesh): a parked car, meshes
  split by material: ``Paint`` (body, cabin), ``Glass`` (windows), ``Tyre`` (wheels).
* ``building.usda`` (USD, Y-up, centimetres, so the scene tool's unit/axis conversion is used):
  a facade with a door and glass windows in frames; materials named ``Wall``, ``Glass``, ``Frame``.
* ``bench.obj`` + ``bench.mtl`` (Wavefront OBJ, Z-up metres): a street bench, ``Wood`` seat and
  ``Metal`` legs.

Usage: ``python tools/make_street_assets.py [OUT_DIR]`` (default examples/assets). The files are
small (well under 1 MB together) and committed; re-running rewrites them identically.
"""

from __future__ import annotations

import sys
from pathlib import Path

import trimesh
from pxr import Gf, Sdf, Usd, UsdGeom, UsdShade, Vt

OUT = Path(__file__).resolve().parents[1] / "examples" / "assets"


#: a base colour per source material (trimesh merges materials that differ only by name)
COLOURS = {"Paint": (180, 20, 20, 255), "Glass": (40, 60, 80, 255), "Tyre": (20, 20, 20, 255)}


def _pbr(material: str):
    colour = COLOURS.get(material, (128, 128, 128, 255))
    return trimesh.visual.TextureVisuals(
        material=trimesh.visual.material.PBRMaterial(name=material, baseColorFactor=colour)
    )


def _box(center, size, name: str, material: str) -> trimesh.Trimesh:
    mesh = trimesh.creation.box(extents=size)
    mesh.apply_translation(center)
    mesh.visual = _pbr(material)
    mesh.metadata["name"] = name
    return mesh


def vehicle() -> trimesh.Scene:
    """A 4.4 x 1.8 x 1.45 m car in Y-up metres: length along +x, up +y, origin on the ground
    under its centre."""
    parts = [
        _box([0.0, 0.45, 0.0], [4.4, 0.6, 1.8], "Body", "Paint"),
        _box([-0.2, 1.05, 0.0], [2.2, 0.55, 1.6], "Cabin", "Paint"),
        _box([0.93, 1.05, 0.0], [0.06, 0.45, 1.45], "Windscreen", "Glass"),
        _box([-0.2, 1.07, 0.81], [1.9, 0.4, 0.02], "WindowLeft", "Glass"),
        _box([-0.2, 1.07, -0.81], [1.9, 0.4, 0.02], "WindowRight", "Glass"),
    ]
    for i, (x, z) in enumerate([(1.4, 0.8), (1.4, -0.8), (-1.4, 0.8), (-1.4, -0.8)]):
        wheel = trimesh.creation.cylinder(radius=0.33, height=0.22, sections=16)
        wheel.apply_translation([x, 0.33, z])  # axis along z (the car's width)
        wheel.visual = _pbr("Tyre")
        wheel.metadata["name"] = f"Wheel{i}"
        parts.append(wheel)
    scene = trimesh.Scene()
    for p in parts:
        scene.add_geometry(p, geom_name=p.metadata["name"], node_name=p.metadata["name"])
    return scene


def bench_obj(path: Path) -> None:
    """A 1.8 m bench in Z-up metres, written as plain OBJ text (one ``o`` per part, ``usemtl``):
    seat and back (Wood) on two legs (Metal)."""
    parts = [
        ([0.0, 0.0, 0.45], [1.8, 0.45, 0.06], "Seat", "Wood"),
        ([0.0, 0.2, 0.75], [1.8, 0.05, 0.35], "Back", "Wood"),
        ([-0.75, 0.0, 0.21], [0.08, 0.4, 0.42], "LegLeft", "Metal"),
        ([0.75, 0.0, 0.21], [0.08, 0.4, 0.42], "LegRight", "Metal"),
    ]
    lines, base = (
        ["# HumV-USD example asset (tools/make_street_assets.py): a bench, Z-up m", "mtllib bench.mtl"],
        1,
    )
    for center, size, name, material in parts:
        box = trimesh.creation.box(extents=size)
        box.apply_translation(center)
        lines += [f"o {name}", f"usemtl {material}"]
        lines += [f"v {x:.4f} {y:.4f} {z:.4f}" for x, y, z in box.vertices]
        lines += [f"f {a + base} {b + base} {c + base}" for a, b, c in box.faces]
        base += len(box.vertices)
    path.write_text("\n".join(lines) + "\n")
    mtl = ["newmtl Wood", "Kd 0.55 0.35 0.2", "newmtl Metal", "Kd 0.3 0.3 0.3"]
    path.with_name("bench.mtl").write_text("\n".join(mtl) + "\n")


def _usd_box(stage, path: str, lo, hi, material: UsdShade.Material) -> None:
    """A closed box (outward counter-clockwise quads) between corners lo and hi [cm, Y-up]."""
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    pts = [
        (x0, y0, z0),
        (x1, y0, z0),
        (x1, y1, z0),
        (x0, y1, z0),
        (x0, y0, z1),
        (x1, y0, z1),
        (x1, y1, z1),
        (x0, y1, z1),
    ]
    quads = [[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]]
    mesh = UsdGeom.Mesh.Define(stage, path)
    mesh.CreatePointsAttr(Vt.Vec3fArray([Gf.Vec3f(*p) for p in pts]))
    mesh.CreateFaceVertexCountsAttr([4] * 6)
    mesh.CreateFaceVertexIndicesAttr([i for q in quads for i in q])
    mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    mesh.CreateExtentAttr(Vt.Vec3fArray([Gf.Vec3f(x0, y0, z0), Gf.Vec3f(x1, y1, z1)]))
    UsdShade.MaterialBindingAPI.Apply(mesh.GetPrim()).Bind(material)


def building(path: Path) -> None:
    """A 12 m wide, 6 m high, 8 m deep building in Y-up centimetres (USD's fallback units):
    front facade at z = +400 cm (the +z side faces the street), door and 2 x 4 windows on it."""
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, 0.01)
    root = UsdGeom.Xform.Define(stage, "/Building")
    stage.SetDefaultPrim(root.GetPrim())
    mats = {n: UsdShade.Material.Define(stage, f"/Building/Looks/{n}") for n in ("Wall", "Glass", "Frame")}
    _usd_box(stage, "/Building/Walls", (-600, 0, -400), (600, 600, 400), mats["Wall"])
    _usd_box(stage, "/Building/Door", (-60, 0, 400), (60, 220, 405), mats["Frame"])
    k = 0
    for row, y in enumerate((120, 370)):
        for x in (-450, -250, 250, 450):
            if row == 0 and abs(x) < 300:
                continue  # the door's bay stays free on the ground floor
            k += 1
            _usd_box(
                stage,
                f"/Building/WindowFrame{k}",
                (x - 75, y - 5, 400),
                (x + 75, y + 155, 404),
                mats["Frame"],
            )
            _usd_box(
                stage,
                f"/Building/WindowGlass{k}",
                (x - 65, y + 5, 404),
                (x + 65, y + 145, 406),
                mats["Glass"],
            )
    stage.GetRootLayer().documentation = (
        "HumV-USD example asset (tools/make_street_assets.py): a building, Y-up cm"
    )
    stage.GetRootLayer().Save()


def main(argv=None) -> int:
    out = Path((argv or sys.argv[1:] or [OUT])[0])
    out.mkdir(parents=True, exist_ok=True)
    vehicle().export(out / "vehicle.glb")
    bench_obj(out / "bench.obj")
    building_path = out / "building.usda"
    if building_path.exists():
        building_path.unlink()
    building(building_path)
    Sdf.Layer.FindOrOpen(str(building_path)).Reload()
    for p in sorted(out.iterdir()):
        print(f"{p}: {p.stat().st_size} bytes")  # noqa: T201 (a script)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
