"""tools/gpu_check.py's CPU side (issue 24.5): the agreement of two renders in units of their
Monte Carlo error (infrared radiance and EO luminance) against closed forms, the one-line refusal
on a Python that lacks the render's packages, and a failed backend failing the check."""

from __future__ import annotations

import ast
import importlib.util
import json
import math
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from humv_usd.groundtruth.labels import CLASSES
from humv_usd.images import write_exr

TOOL = Path(__file__).resolve().parents[1] / "tools" / "gpu_check.py"
H, W = 6, 8


@pytest.fixture(scope="module")
def gc():
    spec = importlib.util.spec_from_file_location("gpu_check", TOOL)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _render_folder(root: Path, ir_value: float, eo_value: float, moved_label: bool) -> Path:
    """A render folder as the render writes it (manifest + EXRs): an LWIR image of radiance
    ``ir_value`` +- 0.1 and an EO image of luminance ``eo_value`` +- 0.2; the left half person."""
    person = CLASSES.index("person")
    cls = np.zeros((H, W), np.float32)
    cls[:, : W // 2] = person
    ids = np.ones((H, W), np.float32)
    depth = np.full((H, W), 10.0, np.float32)
    if moved_label:
        ids[0, 0], depth[0, 0] = 2.0, 10.5
    labels = {"instance_id": ids, "class_id": cls, "depth": depth}
    ir_error = np.full((H, W), 0.1, np.float32)
    ir_error[H - 1, W - 1] = 0.0  # a pixel that states no error (in both renders)
    for name, channels in (
        (
            "lwir",
            {
                "radiance": np.full((H, W), ir_value, np.float32),
                "radiance_stderr": ir_error,
            },
        ),
        ("eo", {"Y": np.full((H, W), eo_value, np.float32), "Y_stderr": np.full((H, W), 0.2, np.float32)}),
    ):
        (root / name).mkdir(parents=True)
        write_exr(root / name / "0000.exr", {**channels, **labels})
    frames = [{"frame": 0, "exr": "lwir/0000.exr"}]
    manifest = {
        "sensors": [{"name": "lwir", "frames": frames}],
        "eo_sensors": [{"name": "eo", "frames": [{"frame": 0, "exr": "eo/0000.exr"}]}],
    }
    (root / "manifest.json").write_text(json.dumps(manifest))
    return root


def test_agreement_is_the_difference_in_units_of_the_combined_error(gc, tmp_path):
    """Radiance 1.3 vs 1.0 with errors 0.1 each: z = 0.3 / sqrt(0.02) per pixel, the image mean's
    z sqrt(n) times that; one pixel without an error differs silently; luminance 2.0 vs 2.4 with
    errors 0.2: z = -0.4 / sqrt(0.08); one pixel's label and depth moved."""
    a = _render_folder(tmp_path / "a", 1.3, 2.0, moved_label=True)
    b = _render_folder(tmp_path / "b", 1.0, 2.4, moved_label=False)
    res = {f["sensor"]: f for f in gc.compare(str(a), str(b))["frames"]}
    assert set(res) == {"lwir", "eo"}  # the visible camera is compared too
    n = H * W
    for name, z, quiet in (("lwir", 0.3 / math.sqrt(0.02), 1), ("eo", -0.4 / math.sqrt(0.08), 0)):
        f = res[name]
        assert f["all"]["pixels"] == n and f["people"]["pixels"] == n // 2
        assert f["all"]["mean"] == pytest.approx(z, rel=1e-5)
        assert f["all"]["std"] == pytest.approx(0.0, abs=1e-5) and f["all"]["beyond_4"] == 0.0
        # the image mean's difference over its standard error sqrt(sum s^2) / n
        assert f["all"]["mean_z"] == pytest.approx(z * n / math.sqrt(n - quiet), rel=1e-5)
        assert f["people"]["mean_z"] == pytest.approx(z * math.sqrt(n // 2), rel=1e-5)
        assert f["all"]["silent"] == pytest.approx(quiet / n)
        assert f["label_pixels_differing"] == pytest.approx(1 / (H * W))
        assert f["depth_max_difference_m"] == pytest.approx(0.5)
    assert res["lwir"]["relative_mean_difference"] == pytest.approx(0.3, rel=1e-5)
    # the compact export (what comes back from a GPU machine) keeps the people's pixels (it
    # dropped the class: "people (0 px)" against a real render, found on an H200)
    summaries = {}
    for name, root in (("x", a), ("y", b)):
        frames = {"frames": [0], "exr": ["lwir/0000.exr"]}
        summaries[name] = {"backend": name, "sensors": {"lwir": frames}}
        gc._export(str(root), summaries[name], str(tmp_path / f"export_{name}"))
    exported = gc.compare(str(tmp_path / "export_x"), str(tmp_path / "export_y"))["frames"]
    assert [f["people"]["pixels"] for f in exported] == [n // 2]
    assert exported[0]["people"]["mean_z"] == pytest.approx(res["lwir"]["people"]["mean_z"], rel=1e-5)


def test_a_python_without_the_renders_packages_is_told_in_one_line(gc, tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(gc.RENDER_PACKAGES, "humv_no_such_module", "humv-no-such-dist")
    assert gc.missing_packages() == ["humv-no-such-dist"]
    assert gc.main(["render", str(tmp_path / "stage.usda"), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "cannot import humv-no-such-dist" in err[0] and "wheels" in err[0]
    assert not (tmp_path / "out").exists()


def test_a_backend_that_fails_fails_the_check(gc, tmp_path, monkeypatch, capsys):
    """A GPU machine whose CUDA render fails must not pass the check on the CPU render alone."""

    def run(cmd, **kwargs):
        backend = cmd[cmd.index("--backend") + 1]
        if backend == "cuda":
            return subprocess.CompletedProcess(cmd, 2, "", "humv-usd: error: backend = 'cuda': no GPU here\n")
        (tmp_path / f"{backend}_summary.json").write_text(json.dumps({"backend": backend, "sensors": {}}))
        return subprocess.CompletedProcess(cmd, 0, f"{backend}: rendered\n", "")

    monkeypatch.setattr(gc.subprocess, "run", run)
    assert gc.main(["check", "stage.usda", "--out", str(tmp_path), "--backends", "cuda,llvm"]) == 1
    assert "cuda: failed (humv-usd: error: backend = 'cuda': no GPU here)" in capsys.readouterr().out
    report = json.loads((tmp_path / "gpu_check.json").read_text())
    assert list(report["failed"]) == ["cuda"] and list(report["backends"]) == ["llvm"]


def _module_level_imports(path: Path) -> set[str]:
    """Top-level package names a module imports when it is loaded (not inside functions)."""
    out, todo = set(), list(ast.parse(path.read_text()).body)
    while todo:
        node = todo.pop()
        if isinstance(node, ast.Import):
            out |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            out.add(node.module.split(".")[0])
        elif isinstance(node, ast.Try | ast.If):
            todo += node.body + node.orelse + [h for t in getattr(node, "handlers", []) for h in t.body]
    return out


def test_the_renders_modules_import_only_the_packages_a_gpu_machine_is_given(gc):
    """Every humv_usd module a render loads imports (when loaded) only the standard library,
    humv_usd and :data:`RENDER_PACKAGES` (the set carried to a GPU machine without network):
    the render once pulled in the thermal tool and trimesh for one constant."""
    code = (
        "import sys, humv_usd.pipeline.render, humv_usd.render.eo, humv_usd.groundtruth.coco; "
        "print('\\n'.join(m.__file__ for n, m in sorted(sys.modules.items()) "
        "if n.startswith('humv_usd') and getattr(m, '__file__', None)))"
    )
    run = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True)
    files = [Path(f) for f in run.stdout.split()]
    assert any(f.parts[-2:] == ("pipeline", "render.py") for f in files)
    assert not [f for f in files if "thermal" in f.parts]  # the thermal tool is not the render's
    extra = {
        top: f.name
        for f in files
        for top in _module_level_imports(f)
        if top not in sys.stdlib_module_names and top != "humv_usd" and top not in gc.RENDER_PACKAGES
    }
    assert not extra, f"the render imports packages outside gpu_check.RENDER_PACKAGES: {extra}"


@pytest.fixture(scope="module")
def bundle():
    spec = importlib.util.spec_from_file_location("gpu_bundle", TOOL.parent / "gpu_bundle.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_gpu_bundle_keeps_every_mitsuba_plugin_the_render_names(bundle):
    """tools/gpu_bundle.py strips Mitsuba to MITSUBA_PLUGINS: every plugin type the render's
    scene dicts name must be among them (else the scene fails to load on the GPU machine), and
    every carried package is pinned in requirements.lock."""
    root = TOOL.parents[1] / "humv_usd"
    named = set()
    for path in [*(root / "render").glob("*.py"), root / "geometry" / "raycast.py"]:
        named |= set(re.findall(r'"type": "([a-z_0-9]+)"', path.read_text()))
    assert {"ply", "moment", "envmap", "spot", "point"} <= named  # the scan sees the scene dicts
    assert named - {"scene"} <= set(bundle.MITSUBA_PLUGINS)
    pinned = bundle.pinned_versions()
    assert all(name.lower() in pinned for name in bundle.CARRY)


def test_stripping_mitsuba_keeps_the_renders_variants_and_plugins(bundle, tmp_path):
    m = tmp_path / "mitsuba"
    (m / "plugins").mkdir(parents=True)
    (m / "include").mkdir()
    (m / "include" / "a.h").write_text("x" * 10)
    names = ["cuda_ad_mono", "cuda_ad_rgb", "llvm_ad_spectral", "llvm_ad_mono_polarized", "scalar_rgb"]
    for name in names:
        (m / f"{name}.cpython-312-x86_64-linux-gnu.so").write_bytes(b"x" * 100)
    for name in ("ply", "moment", "sphere", "bitmap"):
        (m / "plugins" / f"{name}.so").write_bytes(b"x" * 1000)
    (m / "libmitsuba.so").write_bytes(b"x")
    removed = bundle.strip_mitsuba(tmp_path)
    left = sorted(p.relative_to(m).as_posix() for p in m.rglob("*") if p.is_file())
    assert left == [
        "cuda_ad_mono.cpython-312-x86_64-linux-gnu.so",
        "libmitsuba.so",
        "llvm_ad_spectral.cpython-312-x86_64-linux-gnu.so",
        "plugins/moment.so",
        "plugins/ply.so",
        "scalar_rgb.cpython-312-x86_64-linux-gnu.so",
    ]
    assert removed == 2 * 100 + 2 * 1000 + 10
