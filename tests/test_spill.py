"""Time samples spilled to disk while a layer is built (humv_usd.usd.spill, issue 29.5): the
written text is the one the layer holding every sample writes, and the memory a chunked series
needs does not grow with its frame count."""

from __future__ import annotations

import tracemalloc

import numpy as np
from pxr import Sdf, Usd, UsdGeom, Vt

from humv_usd.pipeline.compose import _sha, hold_layer, stage_layer
from humv_usd.usd import spill as SP
from humv_usd.usd.layers import finish, layer_text, new_layer_stage, relative_asset_paths
from humv_usd.usd.thermal import spill_temperatures, write_surface_temperature

FRAMES = SP.CHUNK_FRAMES + 7  # crosses a chunk boundary


def thermal_like_layer(series: dict, spill=None) -> Sdf.Layer:
    """A layer as the thermal tool writes it: overs at several depths, one per-face temperature
    series each (static, time-sampled, or already spilled)."""
    stage = new_layer_stage(30.0, FRAMES, "spill test")
    stage.RemovePrim("/World")
    for path, values in series.items():
        write_surface_temperature(stage.OverridePrim(path), "balance", values, spill)
    return finish(stage)


def series_set(rng):
    walker = 300.0 + rng.random((FRAMES, 37))
    return {
        "/World/Humans/p0/Body": walker,
        "/World/Humans/p0/Clothing/tshirt_black": 290.0 + 5.0 * rng.random((FRAMES, 11)),
        "/World/Scene/Ground": np.full((FRAMES, 5), 288.25),  # every frame the same: a default
        "/World/Scene/Wall": 280.0 + rng.random(4),  # one value per face
        "/World/X": walker[:1] * 1.001,  # one frame
    }


def test_a_spilled_layer_writes_the_text_of_the_whole_layer(tmp_path):
    rng = np.random.default_rng(7)
    series = series_set(rng)
    whole = layer_text(thermal_like_layer(series))
    with SP.SampleSpill(tmp_path, "thermal") as spill:
        skeleton = thermal_like_layer(series, spill)
        assert len(spill.series) == 2  # only the time-sampled ones went to disk
        assert skeleton.ExportToString().count(": [],") == 2  # placeholders, no samples
        sha = spill.export(skeleton, tmp_path / "thermal.usda")
        fragments = [s.path for s in spill.series]
    assert (tmp_path / "thermal.usda").read_text(encoding="utf-8") == whole
    assert sha[:16] == _sha(whole)
    assert not any(p.exists() for p in fragments)  # closed: fragments deleted
    # the round trip reads the values back as float32
    back = Sdf.Layer.FindOrOpen(str(tmp_path / "thermal.usda"))
    stage = Usd.Stage.Open(back)
    got = stage.GetPrimAtPath("/World/Humans/p0/Body").GetAttribute("primvars:humv:thermal:temperature")
    assert np.array_equal(
        np.asarray(got.Get(FRAMES - 1)), series["/World/Humans/p0/Body"][-1].astype(np.float32)
    )


def test_held_samples_expand_a_chunk_at_a_time(tmp_path):
    # radiation samples held between steps (frame i holds row nearest[i]), as the thermal tool's
    # scene slabs: the spilled series is series[nearest], written without building it
    rng = np.random.default_rng(3)
    samples = 280.0 + rng.random((9, 6))
    nearest = np.repeat(np.arange(9), 9)[:FRAMES]
    whole = layer_text(thermal_like_layer({"/World/Scene/Ground": samples[nearest]}))
    with SP.SampleSpill(tmp_path) as spill:
        held = spill_temperatures(spill, samples, nearest)
        assert isinstance(held, SP.Spilled) and held.frames == FRAMES
        spill.export(thermal_like_layer({"/World/Scene/Ground": held}), tmp_path / "t.usda")
    assert (tmp_path / "t.usda").read_text(encoding="utf-8") == whole
    # every sample the same: the default, nothing spilled
    with SP.SampleSpill(tmp_path) as spill:
        flat = spill_temperatures(spill, np.repeat(samples[:1], 9, axis=0), nearest)
        assert flat.shape == (1, 6) and spill.series == []


def test_points_and_other_array_types_spill_too(tmp_path):
    rng = np.random.default_rng(1)
    points = rng.normal(size=(5, 4, 3)).astype(np.float32)
    stage = new_layer_stage(30.0, 5, "points")
    mesh = UsdGeom.Mesh.Define(stage, "/World/M")
    for f in range(5):
        mesh.GetPointsAttr().Set(Vt.Vec3fArray.FromNumpy(points[f]), f)
    whole = layer_text(finish(stage))
    with SP.SampleSpill(tmp_path) as spill:
        stage = new_layer_stage(30.0, 5, "points")
        mesh = UsdGeom.Mesh.Define(stage, "/World/M")
        held = spill.add_array(points, Sdf.ValueTypeNames.Point3fArray)
        SP.SampleSpill.bind(mesh.GetPointsAttr(), held, Vt.Vec3fArray())
        spill.export(finish(stage), tmp_path / "m.usda")
    assert (tmp_path / "m.usda").read_text(encoding="utf-8") == whole


def test_compose_stages_a_layer_by_the_streaming_writer(tmp_path):
    rng = np.random.default_rng(5)
    layer = thermal_like_layer(series_set(rng))
    staged, sha = stage_layer(tmp_path / "thermal.usda", layer)
    text = staged.tmp.read_text(encoding="utf-8")
    assert text == layer_text(layer) and sha == _sha(text)


def test_a_held_layer_reads_back_every_spec_and_sample(tmp_path):
    """compose holds a layer a later build reads as a crate file read back (hold_layer): the
    same text, so the same values for every reader; a point cache and an asset path too."""
    rng = np.random.default_rng(3)
    layer = thermal_like_layer(series_set(rng))
    stage = Usd.Stage.Open(layer)
    mesh = UsdGeom.Mesh.Define(stage, "/World/Humans/p0/Clothing/leggings")
    for f in range(FRAMES):  # float32 points with digits a text round trip must keep
        mesh.GetPointsAttr().Set(Vt.Vec3fArray.FromNumpy(rng.random((9, 3)).astype(np.float32)), f)
    mesh.GetPrim().CreateAttribute("a", Sdf.ValueTypeNames.Asset).Set(Sdf.AssetPath(str(tmp_path / "x.exr")))
    mesh.GetPrim().SetCustomDataByKey("humv:clothing:fix", {"airGapMin_m": 0.1 + 1e-17, "frames": FRAMES})
    held, path = hold_layer(layer, tmp_path, "clothing_p0")
    assert path.parent == tmp_path and ".tmp" in path.name and path.name.startswith(".")  # stale-temp name
    assert layer_text(held) == layer_text(layer)
    del held
    path.unlink()


def _spill_peak(tmp_path, frames: int, faces: int = 2000) -> int:
    """tracemalloc's peak [bytes] while a (frames, faces) series made a chunk at a time is
    spilled (the arrays and the formatted text are Python/numpy allocations)."""

    def chunks():
        for a in range(0, frames, SP.CHUNK_FRAMES):
            n = min(SP.CHUNK_FRAMES, frames - a)
            yield a, np.full((n, faces), 300.0 + a, dtype=np.float32)

    tracemalloc.start()
    try:
        with SP.SampleSpill(tmp_path) as spill:
            spill.add(chunks())
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def test_the_peak_of_a_chunked_spill_does_not_grow_with_frames(tmp_path):
    short = _spill_peak(tmp_path, 2 * SP.CHUNK_FRAMES)
    long = _spill_peak(tmp_path, 16 * SP.CHUNK_FRAMES)
    whole = 16 * SP.CHUNK_FRAMES * 2000 * 4  # the long series as one float32 array
    assert long < 1.25 * short
    assert long < 0.5 * whole


def test_a_layer_without_paths_to_change_is_written_without_a_copy(tmp_path):
    # compose writes relative_asset_paths(layer): a crowd's clothing layer has no asset paths,
    # and copying it held a second copy of its point cache while it was written
    layer = thermal_like_layer(series_set(np.random.default_rng(2)))
    Sdf.CreatePrimInLayer(layer, "/B").referenceList.Prepend(Sdf.Reference("/opt/library/tree.usd"))
    before = layer.ExportToString()
    same = relative_asset_paths(layer, tmp_path / "o" / "layers")
    assert same.identifier == layer.identifier and layer.ExportToString() == before


def test_a_layer_usd_cannot_write_is_an_oserror(tmp_path, monkeypatch):
    # the CLI reports an OSError (a full disk) as one line; USD's writer raises Tf errors
    from pxr import Tf

    def fail(self, path, *args):
        raise Tf.ErrorException("Failed to write layer")

    layer = thermal_like_layer(series_set(np.random.default_rng(4)))
    monkeypatch.setattr(Sdf.Layer, "Export", fail, raising=False)
    try:
        stage_layer(tmp_path / "thermal.usda", layer)
    except OSError as exc:
        assert exc.filename == str(tmp_path / "thermal.usda")
    else:
        raise AssertionError("no OSError")
    assert list(tmp_path.iterdir()) == []  # the temp file is removed
