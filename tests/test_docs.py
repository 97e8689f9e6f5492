"""The manual (docs/, issue 32): it builds with warnings as errors and every cross-reference
resolved, and its generated reference pages name every scenario key, command, option, catalogue
entry and schema attribute. The expectations are taken from the sources themselves (the spec, the
click objects, the schema file read with Sdf), never from the generator's output; the generator is
``docs/_ext/humv_docs.py``."""

from __future__ import annotations

import html
import json
import os
import re
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import click
import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
sys.path.insert(0, str(DOCS / "_ext"))

import humv_docs  # noqa: E402


def _spec_keys():
    """Dotted path of every scenario key, walking the spec's sections (and their subsections)."""
    from humv_usd.scenario.spec import SECTIONS

    out = []
    stack = [(name, sec) for name, sec in SECTIONS.items()]
    while stack:
        prefix, sec = stack.pop()
        out += [f"{prefix}.{k}" for k in sec.keys]
        stack += [(f"{prefix}.{n}", s) for n, s in sec.subsections.items()]
    return out


def _schema_attributes():
    from pxr import Sdf

    layer = Sdf.Layer.FindOrOpen(str(ROOT / "schemas" / "generatedSchema.usda"))
    return {
        (prim.name, prop.name): prop.documentation for prim in layer.rootPrims for prop in prim.properties
    }


def _commands():
    """(command path, command) for every command and group of ``humv-usd``."""
    from humv_usd.cli.main import main

    out, stack = [], [("humv-usd", main)]
    while stack:
        path, cmd = stack.pop()
        out.append((path, cmd))
        if isinstance(cmd, click.Group):
            stack += [(f"{path} {n}", c) for n, c in cmd.commands.items()]
    return out


# ----------------------------------------------------------------------- generators (fast)
def test_every_scenario_key_has_an_entry():
    text = humv_docs.scenario_rst()
    entries = re.findall(r"^\.\. scenario-key:: (\S+)$", text, re.M)
    keys = _spec_keys()
    assert len(keys) > 100
    assert sorted(entries) == sorted(keys), set(keys) ^ set(entries)


def test_scenario_entries_state_range_and_default():
    from humv_usd.scenario.spec import SECTIONS

    text = humv_docs.scenario_rst()
    lat = text.split(".. scenario-key:: general.latitude_deg", 1)[1].split(".. scenario-key::", 1)[0]
    assert "**unit** deg north" in lat and "**range** -90 … 90" in lat and "**required**" in lat
    fps = text.split(".. scenario-key:: general.fps", 1)[1].split(".. scenario-key::", 1)[0]
    assert f"**default** ``{SECTIONS['general'].keys['fps'].default:g}``" in fps
    # a choice lists every allowed value
    act = text.split(".. scenario-key:: human.activity", 1)[1].split(".. scenario-key::", 1)[0]
    for choice in SECTIONS["human"].keys["activity"].choices:
        assert f"``{choice}``" in act


def test_key_unit_rules():
    from humv_usd.scenario.spec import Key

    assert humv_docs.key_unit("resolution", Key("vec", "Image size [width, height] [px].")) == "px"
    assert humv_docs.key_unit("human", Key("str", "Id of a [[human]] entry.")) == ""
    assert humv_docs.key_unit("size_m", Key("vec", "Size, [x, y].")) == "m"
    assert humv_docs.key_unit("cloud_cover", Key("float", "Cloud cover fraction [0-1].")) == "fraction"
    assert humv_docs.key_unit("speed_m_s", Key("float", "Speed.")) == "m/s"


@pytest.mark.parametrize(
    "plain",
    ["a_b and c_ d", "*Glass* = glass", "x | y", "(i) General", "2. second", "back\\slash", "<tag> `code`"],
)
def test_inline_text_survives_restructuredtext(plain):
    """Help text turned into reStructuredText reads back as the same words (docutils parses it),
    with `code` spans as literals."""
    from docutils.core import publish_doctree

    tree = publish_doctree(humv_docs.inline(plain), settings_overrides={"report_level": 2, "halt_level": 2})
    assert tree.astext() == plain.replace("`", "")


def test_every_catalogue_entry_has_a_row_and_its_source():
    from humv_usd.catalog.garments import GARMENTS
    from humv_usd.catalog.materials import LIBRARY
    from humv_usd.catalog.sensors import PRESETS

    materials, garments, sensors = (
        humv_docs.materials_rst(),
        humv_docs.garments_rst(),
        humv_docs.sensors_rst(),
    )
    for name, mat in LIBRARY.items():
        assert materials.count(f"``{name}``") >= 2, name  # a table row and a source entry
        assert humv_docs.inline(mat.source) in materials, name
    for name in GARMENTS:
        assert f"* - ``{name}``" in garments, name
    for name, preset in PRESETS.items():
        assert f"* - ``{name}``" in sensors, name
        assert humv_docs.inline(preset.source) in sensors, name


def test_every_viewpoint_and_activity_has_a_row():
    """Dataset viewpoints (with their sources) on the sensors page; every activity the scenario
    accepts on the activities page, with a metabolic rate and a source cell."""
    from humv_usd.catalog.viewpoints import VIEWPOINTS
    from humv_usd.scenario.spec import ACTIVITIES

    sensors, activities = humv_docs.sensors_rst(), humv_docs.activities_rst()
    for name, vp in VIEWPOINTS.items():
        assert f"* - ``{name}``" in sensors, name
        assert humv_docs.inline(vp.source) in sensors, name
    rows = activities.split("   * - ")[1:]
    assert [r.split("\n")[0] for r in rows[1:]] == [f"``{a}``" for a in ACTIVITIES]
    for row in rows[1:]:
        cells = [c.strip() for c in row.split("\n     - ")]
        assert len(cells) == 5 and all(cells), row
        assert re.search(r"MET|ACSM|walk", cells[3]), row  # a rate
        assert re.search(r"(19|20)\d\d", cells[4]), row  # a dated source


def test_every_schema_attribute_has_an_entry_with_unit_and_range():
    attributes = _schema_attributes()
    assert len(attributes) > 50
    text = humv_docs.schemas_rst()
    blocks = dict(re.findall(r"^\.\. schema-attr:: (\S+)\n\n((?:   .*\n)+)", text, re.M))
    for (cls, name), doc in attributes.items():
        assert f"\n{cls}\n" in text, cls
        assert name in blocks, f"{cls}.{name} has no entry"
        # schema.usda's rule: every attribute doc ends with its Units and Range
        assert "Units:" in doc and "Range:" in doc, f"{cls}.{name}: doc without Units/Range"
        assert "**unit**" in blocks[name] and "**range**" in blocks[name], f"{cls}.{name}"


# ------------------------------------------------------------------------- the site (build)
@pytest.fixture(scope="module")
def site(tmp_path_factory):
    """The whole manual built as ``make docs`` builds it (about 10-15 s on 2 cores)."""
    pytest.importorskip("sphinx")
    out = tmp_path_factory.mktemp("docs")
    run = subprocess.run(
        [
            sys.executable,
            "-m",
            "sphinx",
            "-W",
            "--keep-going",
            "-n",
            "-q",
            "-b",
            "html",
            str(DOCS),
            str(out / "html"),
        ],
        capture_output=True,
        text=True,
        cwd=ROOT,
    )
    assert run.returncode == 0, run.stderr[-4000:]
    yield out / "html"
    shutil.rmtree(out, ignore_errors=True)


def test_site_builds_every_page(site):
    sources = {p.relative_to(DOCS).with_suffix("") for p in DOCS.rglob("*") if p.suffix in (".md", ".rst")}
    sources = {s for s in sources if not str(s).startswith("_")}
    built = {p.relative_to(site).with_suffix("") for p in site.rglob("*.html")}
    assert sources <= built, sources - built
    assert len(sources) >= 15


def test_site_loads_nothing_from_the_network(site):
    """The manual reads offline: no page loads a script, style, image or frame from another host
    (Sphinx's default MathJax is a CDN script; sphinx-mathjax-offline ships MathJax in the build),
    every local script a page loads is in the build, and the pages with maths load MathJax."""
    remote = re.compile(
        r"""<(?:script|img|iframe|source|video|audio|embed)\b[^>]*\bsrc=["']((?:https?:)?//[^"']+)"""
    )
    remote_css = re.compile(r"""<link\b[^>]*\bhref=["']((?:https?:)?//[^"']+)""")
    local = re.compile(r"""<script\b[^>]*\bsrc=["'](?!(?:https?:)?//)([^"'?#]+)""")
    found, missing, maths = [], [], 0
    for page in site.rglob("*.html"):
        text = page.read_text()
        found += [(page.name, u) for u in remote.findall(text) + remote_css.findall(text)]
        for src in local.findall(text):
            if not (page.parent / src).is_file():
                missing.append((page.name, src))
        if 'class="math' in text:
            maths += 1
            assert "_static/mathjax/tex-chtml.js" in text, page
    assert not found, found[:5]
    assert not missing, missing[:5]
    assert maths >= 3  # the physics pages' formulas
    for css in (site / "_static").rglob("*.css"):
        assert not re.search(r"url\(\s*[\"']?(?:https?:)?//", css.read_text()), css.name


def test_cli_reference_has_every_command_and_option(site):
    page = (site / "reference" / "cli.html").read_text()
    ids = set(re.findall(r'id="([^"]+)"', page))
    missing = []
    for path, cmd in _commands():
        slug = path.replace(" ", "-")
        if slug not in ids:
            missing.append(path)
        for param in cmd.params:
            if isinstance(param, click.Option) and not param.hidden:
                for opt in param.opts + param.secondary_opts:
                    if f"cmdoption-{slug}-{opt.lstrip('-')}" not in ids:
                        missing.append(f"{path} {opt}")
    assert not missing, missing


def test_built_reference_has_an_anchor_for_every_key_and_attribute(site):
    """Not only the generated text: the built pages have a linkable entry for every scenario key
    of the spec and every attribute of schemas/generatedSchema.usda."""
    scenario = set(
        re.findall(r'id="scenario-key-([^"]+)"', (site / "reference" / "scenario.html").read_text())
    )
    missing = [k for k in _spec_keys() if html.escape(k) not in scenario]
    schemas = set(re.findall(r'id="schema-attr-([^"]+)"', (site / "reference" / "schemas.html").read_text()))
    names = {name for _, name in _schema_attributes()}
    missing += [n for n in sorted(names) if n.replace(":", "-") not in schemas]
    assert not missing, missing[:10]


def test_generated_pages_link_to_existing_entries(site):
    """The tutorial's links to keys land on the scenario reference's entries."""
    page = (site / "user" / "first-scene.html").read_text()
    targets = set(re.findall(r'href="\.\./reference/scenario\.html#([^"]+)"', page))
    assert "scenario-key-human.clothing" in {html.unescape(t) for t in targets}
    ref = (site / "reference" / "scenario.html").read_text()
    for target in targets:
        assert f'id="{html.unescape(target)}"' in ref


# --------------------------------------------------------------------------- the tutorials
def _run_page(page: str, cwd: Path, env: dict | None = None) -> list[str]:
    """Run a tutorial's ``sh`` and ``python`` blocks in order, as written, in ``cwd`` (which holds
    a link to the repository's ``.venv``); the stdout of each python block."""
    printed = []
    for lang, code in re.findall(r"```(sh|python)\n(.+?)\n```", (DOCS / "user" / page).read_text(), re.S):
        argv = ["bash", "-euo", "pipefail", "-c", code] if lang == "sh" else [sys.executable, "-c", code]
        # a session of its own: what the block left in the background (its process group) is
        # stopped after it, pass or fail
        proc = subprocess.Popen(
            argv,
            cwd=cwd,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env=env,
            start_new_session=True,
        )
        stdout, stderr = proc.communicate()
        try:
            os.killpg(proc.pid, signal.SIGTERM)
        except ProcessLookupError:
            pass
        assert proc.returncode == 0, f"{page}: {code}\n{stderr[-3000:]}"
        if lang == "python":
            printed.append(stdout)
    return printed


@pytest.fixture(scope="module")
def first_scene(tmp_path_factory):
    """docs/user/first-scene.md run as written (~20 s)."""
    cwd = tmp_path_factory.mktemp("tutorial")
    (cwd / ".venv").symlink_to(Path(sys.executable).parents[1])
    shutil.copy(DOCS / "user" / "first.toml", cwd / "first.toml")
    return cwd, _run_page("first-scene.md", cwd)


@pytest.mark.slow
def test_first_scene_tutorial_runs(first_scene):
    cwd, printed = first_scene
    assert (cwd / "out/first/render/coco.json").is_file()
    person, background = map(float, re.findall(r"([\d.]+) K", printed[0]))
    # the person (skin ~306 K under clothes at the 298 K air) differs from the held 310 K ground
    assert 280.0 < person < 315.0 and abs(background - person) > 0.5


@pytest.mark.slow
def test_user_layer_tutorial_runs(first_scene):
    """docs/user/user-layer.md on the first scene's stage: the user layer's emissivity reaches the
    render, and the held 310 K ground looks colder (it reflects surroundings colder than it)."""
    cwd, _ = first_scene
    shutil.copy(DOCS / "user" / "shiny.usda", cwd / "out/first/shiny.usda")
    printed = "".join(_run_page("user-layer.md", cwd))
    rows = re.findall(r"(\w+): ground emissivity ([\d.]+), brightness temperature ([\d.]+) K", printed)
    (_, e0, t0), (_, e1, t1) = [(f, float(e), float(t)) for f, e, t in rows]
    assert 0.9 < e0 < 0.99  # concrete, 8-14 µm (catalogue)
    assert abs(e1 - 0.5) < 0.005  # the user layer's flat spectrum
    assert t1 < t0 - 3.0 and t0 < 311.0


@pytest.mark.slow
def test_aerial_tutorial_runs(tmp_path):
    """docs/user/aerial.md: the camera follows the orbit's closed form, p = c + (R sin psi,
    R cos psi, h) with the compass azimuth psi falling by (v t / R) rad (counter-clockwise), and
    the person is seen in every frame."""
    (tmp_path / ".venv").symlink_to(Path(sys.executable).parents[1])
    shutil.copy(DOCS / "user" / "aerial.toml", tmp_path / "aerial.toml")
    printed = "".join(_run_page("aerial.md", tmp_path))
    rows = re.findall(
        r"frame (\d+): camera at \(([-\d.]+), ([-\d.]+), ([-\d.]+)\) m, .*, (\d+) px visible", printed
    )
    assert len(rows) == 3
    for frame, x, y, z, visible in rows:
        psi = np.pi - 5.0 * 0.5 * int(frame) / 25.0
        assert np.allclose(
            [float(x), float(y), float(z)], [25 * np.sin(psi), 25 * np.cos(psi), 30.0], atol=0.01
        )
        assert int(visible) > 50


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    """docs/user/dataset-tutorial.md run as written (~30 s: the sweep, then the detector)."""
    cwd = tmp_path_factory.mktemp("dataset")
    (cwd / ".venv").symlink_to(Path(sys.executable).parents[1])
    for name in ("first.toml", "shirts.toml"):
        shutil.copy(DOCS / "user" / name, cwd / name)
    return cwd, _run_page("dataset-tutorial.md", cwd)


@pytest.mark.slow
def test_dataset_tutorial_runs(dataset):
    """docs/user/dataset-tutorial.md: 4 variants, each in one split, and every YOLO line is the
    person's visible box of its objects.json, (x0 + x1) / 2W, (y0 + y1) / 2H, (x1 - x0) / W,
    (y1 - y0) / H."""
    tmp_path, (index_out, yolo_out, _) = dataset
    rows = re.findall(r"(v\d{4}) (train|val|test): shirt=(\w+) time=(\w+), person ([\d.]+) K", index_out)
    assert sorted((r[2], r[3]) for r in rows) == sorted(
        (s, t) for s in ("white", "black") for t in ("afternoon", "night")
    )
    assert {r[1] for r in rows} <= {"train", "val", "test"}
    lines = re.findall(r"labels/(\w+)/(v\d{4})_(\d{4})\.txt (.+)", yolo_out)
    assert len(lines) == 4
    dataset = tmp_path / "out" / "shirts"
    for split, variant, frame, line in lines:
        assert split == dict((r[0], r[1]) for r in rows)[variant]
        objects = json.loads(
            next((dataset / "renders" / variant).glob(f"*/lwir/{frame}.objects.json")).read_text()
        )
        x0, y0, x1, y1 = next(o["box_visible"] for o in objects["objects"] if o["class"] == "person")
        w, h = objects["width"], objects["height"]
        cls, *box = line.split()
        assert cls == "0"  # data.yaml: 0 person
        assert np.allclose(
            [float(v) for v in box],
            [(x0 + x1) / 2 / w, (y0 + y1) / 2 / h, (x1 - x0) / w, (y1 - y0) / h],
            atol=1e-6,
        )


@pytest.mark.slow
def test_dataset_tutorial_trains_a_detector(dataset):
    """Step 5 (``humv-usd bench detector`` on the tutorial's dataset): trained on the train split's
    person windows, each person as (1 + JITTER) jittered windows and their mirror images, and
    scored on every split with the variants the index gives it; the held-out images (the same
    person and pose in another shirt or hour) are found."""
    import pandas as pd

    from humv_usd.bench.detector import JITTER

    tmp_path, (_, _, detector_out) = dataset
    index = pd.read_parquet(tmp_path / "out" / "shirts" / "index.parquet")
    by_split = {s: sorted(set(index.variant[index.split == s])) for s in set(index.split)}
    rows = re.findall(r"(\w+): (\d+) image\(s\) of ([v\d, ]+), AP50 ([\d.]+)", detector_out)
    assert {name: sorted(v.split(", ")) for name, _, v, _ in rows} == by_split
    assert all(int(n) == len(by_split[name]) for name, n, _, _ in rows)  # one frame per variant
    (positives,) = re.findall(r"trained on (\d+) person windows", detector_out)
    assert int(positives) == 2 * (1 + JITTER) * len(by_split["train"])  # one person per image
    assert all(float(ap50) > 0.5 for name, _, _, ap50 in rows if name != "train"), rows


@pytest.mark.slow
def test_asset_blender_tutorial_runs(tmp_path):
    """docs/user/asset-blender.md: Blender moves the person 1 m east, seen from 12 m through a
    6 mm lens on 12 um pixels: f / (d p) = 41.7 px; the new crate has its own id and 320 K."""
    pytest.importorskip("bpy")
    (tmp_path / ".venv").symlink_to(Path(sys.executable).parents[1])
    (tmp_path / "examples").symlink_to(ROOT / "examples")
    for name in ("bench_scene.toml", "edit_in_blender.py"):
        shutil.copy(DOCS / "user" / name, tmp_path / name)
    user = tmp_path / "blender_user"  # Blender's user folders, not the machine's
    env = dict(
        os.environ,
        **{
            f"BLENDER_USER_{v.upper()}": str(user / v)
            for v in ("config", "scripts", "resources", "datafiles", "extensions")
        },
    )
    printed = "".join(_run_page("asset-blender.md", tmp_path, env))
    rows = re.findall(r"out/(\w+)/render: (\S+) centre x ([\d.]+) px, surface ([\d.]+) K", printed)
    found = {(folder, prim): (float(x), float(t)) for folder, prim, x, t in rows}
    shift = found["edited", "/World/Humans/p1"][0] - found["bench", "/World/Humans/p1"][0]
    assert shift == pytest.approx(1.0 * 6e-3 / (12.0 * 12e-6), abs=1.0)
    assert found["bench", "/World/Scene/bench"][1] == pytest.approx(300.0, abs=1e-3)
    assert found["edited", "/World/Scene/crate"][1] == pytest.approx(320.0, abs=1e-3)
    assert ("bench", "/World/Scene/crate") not in found


@pytest.mark.slow
def test_cluster_tutorial_runs(dataset):
    """docs/user/cluster-tutorial.md: the sweep on a scheduler and 2 worker processes gives the
    in-process dataset's images and labels byte for byte."""
    cwd, _ = dataset
    (printed,) = _run_page("cluster-tutorial.md", cwd)
    same, total = map(int, re.search(r"(\d+) of (\d+) images and label files identical", printed).groups())
    assert total >= 4 * 2 + 4 and same == total  # 4 EXRs, 4 objects.json, COCO, YOLO


def test_gallery_shows_every_image_it_lists(site):
    """docs/gallery/gallery.json (make gallery) names files that exist, and the gallery page shows
    each render and its label overlay."""
    index = DOCS / "gallery" / "gallery.json"
    if not index.is_file():
        pytest.skip("no gallery rendered (make gallery)")
    entries = json.loads(index.read_text())
    page = (site / "gallery.html").read_text()
    for e in entries:
        for name in (e["image"], e["labels"]):
            assert (DOCS / "gallery" / name).is_file(), name
            assert (site / "_images" / name).is_file() and f"_images/{name}" in page, name


@pytest.mark.parametrize("example", ["humvvex", "street"])
def test_gallery_adds_nir_and_swir_cameras_with_the_presets_field_of_view(example):
    """The gallery (docs/_ext/gallery.py) renders the reflective bands the examples lack: a NIR and a
    SWIR camera beside the EO camera, looking where it looks, each with its preset's field of view
    (sensor width = pixels x pitch kept through the binning and the 1/SCALE), in a scenario the
    loader accepts."""
    import tomllib

    import gallery

    from humv_usd.catalog.sensors import PRESETS
    from humv_usd.scenario.load import validate

    source = ROOT / "examples" / f"{example}.toml"
    raw = tomllib.loads(source.read_text())
    gallery._absolute_paths(raw, source.parent)
    gallery._reflective_cameras(raw)
    gallery._smaller_cameras(raw)
    sensors = {s["id"]: s for s in raw["sensor"]}
    eo = sensors["eo_rgb"]
    for sid, band in (("nir", "NIR"), ("swir", "SWIR")):
        s = sensors[sid]
        preset = PRESETS[s["preset"]]
        assert preset.band == band
        for axis in (0, 1):
            got = s["resolution"][axis] * s["pixel_pitch_um"]
            assert got == pytest.approx(preset.resolution[axis] * preset.pixel_pitch_um)
        assert s["look_at_m"] == eo["look_at_m"] and s["position_m"] != eo["position_m"]
    scenario = validate(raw, source)
    assert {"nir", "swir"} <= {s["id"] for s in scenario.data["sensor"]}


def test_every_physics_module_has_a_page():
    """A model added to humv_usd/physics/ without a physics page fails here."""
    pages = "\n".join(p.read_text() for p in (DOCS / "physics").glob("*.rst"))
    listed = set(re.findall(r"humv_usd\.[\w.]+", pages))
    modules = {
        f"humv_usd.physics.{p.stem}"
        for p in (ROOT / "humv_usd" / "physics").glob("*.py")
        if p.stem not in ("__init__", "checks")  # argument checks, not a model
    }
    assert modules <= listed, sorted(modules - listed)


def test_every_test_a_page_names_exists():
    """The physics pages' measured agreements name the tests that assert them: a renamed or
    removed test fails here, so no page cites a check that no longer runs."""
    cited = set()
    for page in DOCS.rglob("*"):
        if page.suffix in (".md", ".rst"):
            cited |= set(re.findall(r"tests/(test_\w+\.py)::(test_\w+)", page.read_text()))
    assert len(cited) >= 60
    missing = []
    for file, name in sorted(cited):
        path = ROOT / "tests" / file
        # module-level test functions (a def at column 0)
        defined = set(re.findall(r"^def (test_\w+)\(", path.read_text(), re.M)) if path.is_file() else set()
        if name not in defined:
            missing.append(f"tests/{file}::{name}")
    assert not missing, missing
    physics = [p for p in (DOCS / "physics").glob("*.rst")]
    without = [p.name for p in physics if "Measured agreement" not in p.read_text()]
    assert not without, without


def test_physics_figures_are_drawn_from_their_csvs(site):
    """Every figure of the physics pages is drawn from committed bench CSVs that say which
    command, commit and date made them, and is in the built site."""
    import humv_figures

    for name, (csvs, _, _) in humv_figures.FIGURE_SPECS.items():
        for csv_name in csvs:
            header, rows = humv_figures.read_csv(humv_figures.DATA / csv_name)
            assert rows and any("commit" in h for h in header), csv_name
        assert (site / "_images" / f"{name}.svg").is_file(), name
    pages = "".join((site / "physics" / f"{p}.html").read_text() for p in ("render", "physiology", "garment"))
    for name in humv_figures.FIGURE_SPECS:
        assert f"_images/{name}.svg" in pages, name


def test_docstring_prose_survives_any_markup():
    """Physics pages show docstrings as written: numpydoc sections become lists, a reference
    ``.. [1]`` stays text, and nothing in them can make docutils report a problem."""
    from docutils import nodes
    from docutils.core import publish_doctree

    doc = r"""Summary with |pipes|, *stars* and trailing_ underscores; :math:`\sigma T^4`.

    - a bullet
      continued
    - (i) another

    Parameters
    ----------
    x : float
        The value [K].

    References
    ----------
    .. [1] Author (2000), A book.
    """
    rst = humv_docs.prose_rst(doc)
    tree = publish_doctree(rst, settings_overrides={"report_level": 1, "halt_level": 1})
    text = tree.astext()
    assert "|pipes|, stars and trailing_ underscores" in text
    assert [n.astext() for n in tree.findall(nodes.emphasis)] == ["stars"]
    assert [n.astext() for n in tree.findall(nodes.math)] == [r"\sigma T^4"]
    assert "[1] Author (2000), A book." in text and "x : float: The value [K]." in text
    assert "a bullet continued" in text
