"""Contact sheet of randomly drawn people (issue 29): EO and LWIR mesh-only renders.

    .venv/bin/python tools/people_contact_sheet.py OUT_DIR [N] [SEED]

Draws N people (default 50) with :func:`humv_usd.human.population.sample_people` (ages 2-90),
dresses each in a random outfit from the catalogue (hair from the sampler; a top, bottoms or a
dress, sometimes an outer layer, a hat and accessories), fits and layers the outfit at rest
(:func:`humv_usd.clothing.collide.dress` / ``simulate``: the same fit and collision fix as the
clothing tool) and renders all of them side by side with Mitsuba (orthographic, front view):

* EO: each mesh a diffuse surface of its library material's display colour (reflectance at
  0.65 / 0.55 / 0.45 µm; half of the tops, bottoms and bags dyed a random colour,
  :mod:`humv_usd.catalog.dyes`) under a sun and a uniform sky;
* LWIR (illustration, not the thermal tool): each mesh emits eps(10 µm) B(10 µm, T) with skin at
  306 K, each garment at the temperature of a series resistance model (skin -> fabrics and air
  gaps under it -> 0.11 m2 K/W to the 293 K air), props at the air temperature.

Writes OUT_DIR/people_eo.png, people_lwir.png, people.json (who wears what) and
population_stats.json (the drawn statistics against the sources).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from humv_usd.catalog.dyes import COLOURS, garment_material  # noqa: E402
from humv_usd.catalog.dyes import material as library_material  # noqa: E402
from humv_usd.catalog.materials import LIBRARY  # noqa: E402
from humv_usd.catalog.skin import skin_material_name  # noqa: E402
from humv_usd.clothing.collide import dress, simulate  # noqa: E402
from humv_usd.clothing.fit import prepare  # noqa: E402
from humv_usd.human.body import build_body  # noqa: E402
from humv_usd.human.population import ANSUR2, sample_people  # noqa: E402
from humv_usd.human.skeleton import forward_kinematics, skinning_matrices  # noqa: E402
from humv_usd.physics.planck import spectral_radiance  # noqa: E402

TOPS = ("tshirt_white", "tshirt_black", "longsleeve", "sweater", "hoodie")
BOTTOMS = ("jeans", "trousers", "shorts", "skirt", "leggings", "uniform_trousers")
OUTER = (None, None, "jacket", "fleece_jacket", "winter_coat")
HATS = (None, None, None, "cap", "beanie", "helmet")
EXTRAS = {"glasses": 0.2, "backpack": 0.2, "bag": 0.15, "phone": 0.1, "gloves": 0.1, "scarf": 0.1}
T_SKIN, T_AIR, R_SURFACE = 306.0, 293.0, 0.11
AIR_K = 0.026  # W m-1 K-1, still air in the gaps (capped at 8 mm of still air per gap)


def outfit(rng, person) -> list[str]:
    """A random outfit for ``person`` (sets ``person["clothing_colors"]`` too)."""
    wear = list(person["clothing"])  # hair from the sampler
    if person["sex"] == "female" and rng.random() < 0.2:
        wear.append("dress")
    else:
        top = TOPS[int(rng.integers(len(TOPS)))]
        bottom = BOTTOMS[int(rng.integers(len(BOTTOMS)))]
        wear += [top, bottom]
        outer = OUTER[int(rng.integers(len(OUTER)))]
        if outer and top != "hoodie":
            wear.append(outer)
    hat = HATS[int(rng.integers(len(HATS)))]
    if hat and "hoodie" not in wear:
        wear.append(hat)
    wear.append("boots" if rng.random() < 0.2 else "shoes")
    for name, p in EXTRAS.items():
        if rng.random() < p:
            wear.append(name)
    # half of the tops, bottoms, dresses and bags in another colour (human.clothing_colors)
    names = list(COLOURS)
    person["clothing_colors"] = {
        g: names[int(rng.integers(len(names)))]
        for g in wear
        if g in (*TOPS, *BOTTOMS, "dress", "backpack", "bag", "beanie") and rng.random() < 0.5
    }
    return wear


def garment_temperature(g, under) -> float:
    """Outer-surface temperature [K] of garment ``g`` over the garments ``under`` it (series
    resistances: fabric thickness / conductivity + min(ease, 8 mm) / k_air per layer)."""
    if g.is_prop:
        return T_AIR
    r = 0.0
    for x in [*under, g]:
        m = LIBRARY[x.fabric]
        r += m.thickness / m.conductivity + min(max(x.ease, 0.0), 0.008) / AIR_K
    return T_AIR + (T_SKIN - T_AIR) * R_SURFACE / (R_SURFACE + r)


def people_meshes(people, rng):
    """[(points (n, 3), triangles (m, 3), eo_rgb, lwir_radiance)] per mesh, per person."""
    b10 = float(spectral_radiance(10.0, T_SKIN))
    out = []
    for person in people:
        wear = outfit(rng, person)
        person["wearing"] = wear
        body = build_body(
            person["sex"], person["age_yr"], person["stature_m"], person["mass_kg"], person["build"],
            person["proportions"],
        )  # fmt: skip
        person["fit"] = {"uniform_scale": body.uniform_scale, "lateral_scale": body.lateral_scale}
        rig = prepare(body)
        q = np.zeros((1, len(rig.skeleton.names), 4))
        q[..., 0] = 1.0
        skin = skinning_matrices(
            rig.skeleton, forward_kinematics(rig.skeleton, q, rig.skeleton.rest_positions[:1])
        )
        sim = simulate(dress(rig, wear), skin)
        skin_mat = LIBRARY[skin_material_name(person["skin_tone"])]
        meshes = [(rig.mesh.points, rig.triangles, skin_mat.display_color, 0.98 * b10 / b10)]
        done = []
        for anim in sim.garments:
            g = anim.fitted.garment
            m = library_material(
                garment_material(g.name, person["clothing_colors"], person.get("hair_color"))
            )
            t = garment_temperature(g, [d for d in done if not d.is_prop])
            eps = float(m.at(10.0, "emissivity"))
            meshes.append(
                (
                    anim.posed[0],
                    anim.fitted.triangles,
                    m.display_color,
                    eps * float(spectral_radiance(10.0, t)) / b10,
                )
            )
            done.append(g)
        out.append(meshes)
        print(f"{len(out):3d} {person['sex']:6s} {person['age_yr']:5.1f} yr {person['stature_m']:.2f} m "
              f"{person['mass_kg']:5.1f} kg {person['skin_tone']:3s} {' '.join(wear)}", flush=True)  # fmt: skip
    return out


def render(all_meshes, people, kind: str, path: Path, columns: int = 10, px_per_m: int = 70):
    import tempfile

    import mitsuba as mi
    from PIL import Image

    mi.set_variant("llvm_ad_rgb" if "llvm_ad_rgb" in mi.variants() else "scalar_rgb")
    tmp = Path(tempfile.mkdtemp(prefix="people-"))
    cell_w, cell_h = 1.15, 2.05
    rows = (len(all_meshes) + columns - 1) // columns
    width, height = columns * cell_w, rows * cell_h
    scene = {
        "type": "scene",
        "integrator": {"type": "direct"} if kind == "eo" else {"type": "path", "max_depth": 1},
    }
    for k, meshes in enumerate(all_meshes):
        dx = (k % columns + 0.5) * cell_w - width / 2
        dz = (rows - 1 - k // columns) * cell_h
        for j, (pts, tris, rgb, lw) in enumerate(meshes):
            path_ply = tmp / f"m{k}_{j}.ply"
            _write_ply(path_ply, np.asarray(pts) + [dx, 0.0, dz], np.asarray(tris))
            d = {"type": "ply", "filename": str(path_ply), "face_normals": True}
            if kind == "eo":
                d["bsdf"] = {
                    "type": "twosided",
                    "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": list(rgb)}},
                }
            else:
                d["bsdf"] = {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.0] * 3}}
                d["emitter"] = {"type": "area", "radiance": {"type": "rgb", "value": [float(lw)] * 3}}
            scene[f"m{k}_{j}"] = d
    if kind == "eo":
        scene["sky"] = {"type": "constant", "radiance": {"type": "rgb", "value": [0.45, 0.5, 0.6]}}
        scene["sun"] = {
            "type": "directional",
            "direction": [-0.4, 0.8, -0.6],
            "irradiance": {"type": "rgb", "value": [2.5] * 3},
        }
    distance = 200.0  # nearly orthographic: a narrow field of view from far away
    scene["camera"] = {
        "type": "perspective",
        "fov_axis": "y",
        "fov": float(np.degrees(2 * np.arctan(height / 2 / distance))),
        "to_world": mi.ScalarTransform4f.look_at(
            origin=[0.0, -distance, height / 2], target=[0.0, 0.0, height / 2], up=[0, 0, 1]
        ),
        "film": {"type": "hdrfilm", "width": int(width * px_per_m), "height": int(height * px_per_m), "rfilter": {"type": "box"}},
        "sampler": {"type": "independent", "sample_count": 8},
    }  # fmt: skip
    img = np.asarray(mi.render(mi.load_dict(scene)))[..., :3]
    if kind == "eo":
        img = np.clip(img / 1.2, 0, 1) ** (1 / 2.2)
    else:  # LWIR: grey, 280 K background black, skin white
        lo = float(spectral_radiance(10.0, 280.0) / spectral_radiance(10.0, T_SKIN))
        img = np.clip((img[..., :1] - lo) / (1.0 - lo), 0, 1).repeat(3, axis=2)
    Image.fromarray((img * 255).astype(np.uint8)).save(path)


def _write_ply(path: Path, points: np.ndarray, tris: np.ndarray) -> None:
    head = (
        f"ply\nformat binary_little_endian 1.0\nelement vertex {len(points)}\nproperty float x\n"
        f"property float y\nproperty float z\nelement face {len(tris)}\n"
        "property list uchar int vertex_indices\nend_header\n"
    )
    faces = np.zeros(len(tris), dtype=[("n", "u1"), ("v", "<i4", 3)])
    faces["n"], faces["v"] = 3, tris
    path.write_bytes(head.encode("ascii") + points.astype("<f4").tobytes() + faces.tobytes())


def stats(people) -> dict:
    out = {}
    for sex in ("male", "female"):
        adults = [p for p in people if p["sex"] == sex and p["age_yr"] >= 20]
        if adults:
            h = np.array([p["stature_m"] for p in adults])
            bmi = np.array([p["mass_kg"] / p["stature_m"] ** 2 for p in adults])
            mu_h, sd_h, mu_b, sd_b = ANSUR2[sex]
            out[sex] = {
                "n_adults": len(adults),
                "stature_m": [round(float(h.mean()), 4), round(float(h.std(ddof=1)), 4)]
                if len(h) > 1
                else None,
                "ansur2_stature_m": [mu_h, sd_h],
                "ln_bmi": [round(float(np.log(bmi).mean()), 4), round(float(np.log(bmi).std(ddof=1)), 4)]
                if len(h) > 1
                else None,
                "ansur2_ln_bmi": [mu_b, sd_b],
            }
    out["children_under_20"] = sum(p["age_yr"] < 20 for p in people)
    out["skin_tones"] = {
        t: sum(p["skin_tone"] == t for p in people) for t in ("I", "II", "III", "IV", "V", "VI")
    }
    return out


def main(argv) -> int:
    out = Path(argv[1])
    n = int(argv[2]) if len(argv) > 2 else 50
    seed = int(argv[3]) if len(argv) > 3 else 29
    out.mkdir(parents=True, exist_ok=True)
    people = sample_people(n, seed, age_yr=(2.0, 90.0))
    meshes = people_meshes(people, np.random.default_rng(seed))
    render(meshes, people, "eo", out / "people_eo.png")
    render(meshes, people, "lwir", out / "people_lwir.png")
    (out / "people.json").write_text(json.dumps(people, indent=1))
    (out / "population_stats.json").write_text(json.dumps(stats(people), indent=1))
    big = sample_people(5000, seed, age_yr=(20.0, 90.0))
    (out / "population_stats_5000_adults.json").write_text(json.dumps(stats(big), indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv))
