"""Per-body-region statistics (seed Table 2) and the regions command with a real image."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner
from numpy.testing import assert_allclose
from pxr import Sdf, UsdGeom, Vt
from test_groundtruth import camera, label, material, mesh, new_stage, read_exr, sphere_mesh

from humv_usd.cli.main import main
from humv_usd.errors import InputError
from humv_usd.groundtruth import regions as R
from humv_usd.human import labels as AL
from humv_usd.pipeline.render import render_stage, writers


def test_region_stats_match_numpy_on_unions():
    rng = np.random.default_rng(1)
    region = rng.integers(0, 20, size=(30, 40))
    value = rng.normal(100.0, 5.0, size=region.shape)
    temp = rng.normal(305.0, 1.0, size=region.shape)
    stats = R.region_stats(region, value, temp)
    assert list(stats) == list(AL.SEED_TABLE2_REGIONS)
    torso = np.isin(region, [AL.REGION_ID[n] for n in ("abdomen", "back", "pelvis")])
    assert stats["Torso"]["pixels"] == torso.sum()
    assert_allclose(stats["Torso"]["mean"], value[torso].mean())
    assert_allclose(stats["Torso"]["std"], value[torso].std())
    assert_allclose(stats["Torso"]["temperature_mean_k"], temp[torso].mean())
    body = region > 0
    assert_allclose(stats["Full body"]["mean"], value[body].mean())
    assert_allclose(stats["Hat"]["std"], value[region == AL.REGION_ID["head"]].std())


def test_image_regions_per_person_and_quantity():
    region = np.array([[0, 4, 4, 2], [0, 4, 2, 2]], dtype=float)
    inst = np.array([[0, 1, 1, 5], [0, 5, 5, 5]], dtype=float)
    rad = np.arange(8, dtype=float).reshape(2, 4)
    bt = 300.0 + rad
    ch = {"body_region": region, "instance_id": inst, "radiance": rad, "brightness_temperature": bt}
    out = R.image_regions(ch)
    assert [o["instance_id"] for o in out] == [1, 5] and out[0]["quantity"] == "radiance"
    assert_allclose(out[0]["regions"]["Chest"]["mean"], (1 + 2) / 2)
    assert out[1]["regions"]["Chest"]["pixels"] == 1 and out[1]["regions"]["Face"]["pixels"] == 3
    assert R.image_regions({**ch, "counts": 10 * rad})[0]["quantity"] == "counts"
    assert_allclose(R.image_regions({**ch, "counts": 10 * rad})[0]["regions"]["Chest"]["mean"], 15.0)
    with pytest.raises(InputError, match="body_region"):
        R.image_regions({"radiance": rad})


@pytest.fixture(scope="module")
def render_dir(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("regions")
    stage = new_stage(tmp / "stage.usda")
    m = material(stage, "/World/Materials/skin", 0.98)
    label(stage.DefinePrim("/World/Humans/p1", "Xform"), 1, "person")
    pts, counts, idx = sphere_mesh((0.0, 0.0, 1.0), 0.5, 1)
    nf = len(counts)
    body = mesh(
        stage, "/World/Humans/p1/Body", pts, counts, idx, m, 300.0 + 0.1 * (np.arange(nf) % 19)
    ).GetPrim()
    UsdGeom.PrimvarsAPI(body).CreatePrimvar(
        "humv:label:bodyRegion", Sdf.ValueTypeNames.IntArray, UsdGeom.Tokens.uniform
    ).Set(Vt.IntArray((1 + np.arange(nf) % 19).tolist()))
    camera(stage, "cam", (0.0, -4.0, 1.0), (0.0, 0.0, 1.0), res=(40, 30))
    stage.Save()
    manifest = render_stage(tmp / "stage.usda", tmp / "out", spp=2, annotators=["regions", "masks"])
    return tmp / "out", manifest


def test_render_writes_regions_json(render_dir):
    out, manifest = render_dir
    doc = json.loads((out / "regions.json").read_text())
    [rec] = doc["images"]
    ch = read_exr(out / rec["exr"])
    assert rec["quantity"] == ("counts" if "counts" in ch else "radiance")
    filled = 0
    for name, members in AL.SEED_TABLE2_REGIONS.items():
        sel = np.isin(ch["body_region"], [AL.REGION_ID[n] for n in members])
        assert rec["regions"][name]["pixels"] == sel.sum()
        if sel.any():
            filled += 1
            assert_allclose(
                rec["regions"][name]["temperature_mean_k"],
                ch["brightness_temperature"][sel].mean(),
                rtol=1e-6,
            )
            assert_allclose(rec["regions"][name]["std"], ch[rec["quantity"]][sel].std(), rtol=1e-4, atol=1e-9)
    assert filled >= 8
    assert manifest["ground_truth"]["files"]["regions"] == "regions.json"


def test_regions_command_against_a_real_image(render_dir, tmp_path):
    out, _ = render_dir
    ch = read_exr(out / "cam" / "0000.exr")
    real = tmp_path / "real.exr"
    writers.write_exr(real, {"Y": ch["brightness_temperature"] - 1.5})  # a "real" image 1.5 K colder
    masks = out / "cam" / "0000.region_ids.png"
    result = CliRunner().invoke(
        main, ["regions", str(out), "--real", str(real), "--masks", str(masks), "--quantity", "temperature"]
    )
    assert result.exit_code == 0, result.output
    rows = [line.split() for line in result.output.splitlines() if line[:2].strip().isdigit()]
    assert len(rows) == len(AL.SEED_TABLE2_REGIONS)
    diffs = [float(r[-1]) for r in rows if r[-1] != "-"]
    assert len(diffs) >= 10
    assert_allclose(diffs, 1.5, atol=2e-4)  # sim - real, region by region
    assert (out / "regions.json").is_file()
    # masks of another size: one line, exit 2
    writers.write_png(tmp_path / "small.png", np.zeros((3, 4), dtype=np.uint8))
    bad = CliRunner().invoke(
        main, ["regions", str(out), "--real", str(real), "--masks", str(tmp_path / "small.png")]
    )
    assert bad.exit_code == 2 and "size" in bad.output
    lonely = CliRunner().invoke(main, ["regions", str(out), "--real", str(real)])
    assert lonely.exit_code == 2
    missing = CliRunner().invoke(main, ["regions", str(tmp_path)])
    assert missing.exit_code == 2 and "manifest.json" in missing.output


def test_real_counts_png_compared_in_counts(render_dir, tmp_path):
    """A 16-bit PNG of counts (the render's own <frame>_counts.png format) is read as stored
    integers, not rescaled to 0..1, so sim - real is in counts."""
    out, _ = render_dir
    ch = read_exr(out / "cam" / "0000.exr")
    assert "counts" in ch
    real = tmp_path / "real_counts.png"
    writers.write_png16(real, np.clip(ch["counts"] - 100.0, 0, 65535).astype(np.uint16))
    masks = out / "cam" / "0000.region_ids.png"
    result = CliRunner().invoke(
        main, ["regions", str(out), "--real", str(real), "--masks", str(masks), "--quantity", "counts"]
    )
    assert result.exit_code == 0, result.output
    rows = [line.split() for line in result.output.splitlines() if line[:2].strip().isdigit()]
    diffs = [float(r[-1]) for r in rows if r[-1] != "-"]
    assert len(diffs) >= 10
    assert_allclose(diffs, 100.0, atol=0.05)


def test_eo_images_are_in_the_table_by_luminance(tmp_path):
    """EO sensors (manifest "eo_sensors", EXR without counts or radiance) get region rows of
    their luminance Y and no temperature."""
    region = np.zeros((4, 6))
    region[:, :3] = AL.BODY_REGIONS.index(AL.BODY_REGIONS[0]) + 1
    y = np.where(region > 0, 0.25, 0.9)
    (tmp_path / "eo").mkdir()
    writers.write_exr(
        tmp_path / "eo" / "0000.exr",
        {"Y": y, "body_region": region, "instance_id": (region > 0).astype(float)},
    )
    (tmp_path / "manifest.json").write_text(
        json.dumps(
            {"sensors": [], "eo_sensors": [{"name": "eo", "frames": [{"frame": 0, "exr": "eo/0000.exr"}]}]}
        )
    )
    [rec] = R.render_regions(tmp_path)
    assert rec["sensor"] == "eo" and rec["quantity"] == "Y"
    full = rec["regions"][next(iter(R.TABLE2))]
    assert full["pixels"] == 12 and full["mean"] == pytest.approx(0.25) and full["std"] == pytest.approx(0.0)
    assert "temperature_mean_k" not in full  # no temperature for EO


def test_render_computes_regions_without_reading_its_images_back(render_dir, tmp_path, monkeypatch):
    """The render hands each written image's channels to the ground truth (image_written), so
    regions.json needs no read-back of the EXRs; the records equal those of the read-back."""
    out, _ = render_dir
    expected = R.render_regions(out)  # from the EXRs on disk
    stage_path = out.parent / "stage.usda"

    def no_read(*args, **kwargs):
        raise AssertionError("regions read an EXR back")

    monkeypatch.setattr(R, "read_image", no_read)
    render_stage(stage_path, tmp_path / "again", spp=2, annotators=["regions", "masks"])
    doc = json.loads((tmp_path / "again" / "regions.json").read_text())
    assert [r["exr"] for r in doc["images"]] == [r["exr"] for r in expected]
    for got, want in zip(doc["images"], expected):
        for name, row in want["regions"].items():
            assert got["regions"][name]["pixels"] == row["pixels"]
            if row["pixels"]:
                assert_allclose(got["regions"][name]["mean"], row["mean"], rtol=1e-9)


def test_region_lookup_and_colour_table_equal_the_set_operations():
    from humv_usd.groundtruth import labels as GL
    from humv_usd.groundtruth.regions import region_stats

    rng = np.random.default_rng(5)
    region = rng.integers(0, 21, (60, 80))
    value = rng.normal(10.0, 2.0, region.shape)
    select = rng.random(region.shape) > 0.3
    by_lookup = region_stats(region, value, value + 280.0, select=select)
    by_isin = region_stats(region.astype(float), value, value + 280.0, select=select)  # np.isin path
    assert by_lookup == by_isin
    inst = rng.integers(0, 7, (30, 40)) * 1000
    ids, inverse = np.unique(inst, return_inverse=True)
    assert np.array_equal(
        GL.colour_instances(inst), GL.instance_colours(ids)[inverse].reshape(inst.shape + (3,))
    )
