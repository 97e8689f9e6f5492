"""The codeless HumV USD schemas: registered, applicable where allowed, documented, up to date."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from pxr import Sdf, Usd

# Registration must happen before any stage exists: import the package first.
import humv_usd  # noqa: F401  (registers the schemas)
from humv_usd.scenario.spec import ACTIVITIES
from humv_usd.usd import schemas as hs

REPO = Path(__file__).resolve().parents[1]
SCHEMAS_DIR = REPO / "schemas"

# The contract: docs/architecture.md, "Schemas" table.
APPLIES_TO = {
    hs.SCENARIO_API: {"Xform", "Scope"},
    hs.ENVIRONMENT_API: {"Scope", "Xform"},
    hs.ATMOSPHERE_API: {"Scope", "Xform"},
    hs.ATMOSPHERE_PATH_API: {"Scope"},
    hs.MATERIAL_API: {"Material"},
    hs.AVATAR_API: {"SkelRoot", "Xform"},
    hs.CLOTHING_API: {"Mesh"},
    hs.THERMAL_API: {"Mesh"},
    hs.SENSOR_API: {"Camera"},
    hs.LABEL_API: {"Xform", "Scope", "Mesh", "SkelRoot"},
}
PRIM_TYPES = ["Xform", "Scope", "Mesh", "Camera", "Material", "SkelRoot", "Sphere"]

ALLOWED_TOKENS = {
    hs.ATMOSPHERE_MODEL: ["analytic", "lowtran7"],
    hs.ATMOSPHERE_PROFILE: [
        "tropical",
        "midlatitudeSummer",
        "midlatitudeWinter",
        "subarcticSummer",
        "subarcticWinter",
        "usStandard1976",
    ],
    hs.AVATAR_SEX: ["male", "female"],
    hs.AVATAR_FITNESS: ["low", "average", "high", "athlete"],
    hs.AVATAR_ACTIVITY: list(ACTIVITIES),
    hs.THERMAL_MODEL: ["fixed", "twoNode", "jos3", "slab", "balance"],
    hs.SENSOR_BAND: ["EO", "NIR", "SWIR", "MWIR", "LWIR"],
    hs.SENSOR_PLATFORM: ["tripod", "mast", "aerial", "vehicle", "drone", "handheld"],
    hs.SENSOR_AGC: ["none", "linear", "histogram", "plateau"],
    hs.SENSOR_VIGNETTING: ["none", "cos4"],
    hs.SENSOR_MOTION_BLUR: ["none", "camera"],
    hs.LABEL_CLASS: [
        "person",
        "ground",
        "building",
        "prop",
        "panel",
        "vegetation",
        "vehicle",
        "other",
        "animal",
        "lamp",
        "hvac",
        "fire",
    ],
}
# The table gives no token set for the garment: it names garments of the clothing library.
OPEN_TOKENS = {hs.CLOTHING_GARMENT}

ATTRIBUTE_CONSTANTS = {
    name: value
    for name, value in vars(hs).items()
    if name.isupper() and isinstance(value, str) and value.startswith(("humv:", "primvars:humv:"))
}


def _stage_with(prim_type: str, path: str = "/P") -> tuple[Usd.Stage, Usd.Prim]:
    """A fresh in-memory stage and one prim on it (keep the stage: the prim dies with it)."""
    stage = Usd.Stage.CreateInMemory()
    return stage, stage.DefinePrim(path, prim_type)


def _definition(schema: str) -> Usd.PrimDefinition:
    return Usd.SchemaRegistry().FindAppliedAPIPrimDefinition(schema)


@pytest.mark.parametrize("schema", hs.SCHEMAS)
def test_schema_registered(schema):
    assert _definition(schema) is not None
    assert Usd.SchemaRegistry().IsAppliedAPISchema(schema)


def test_register_schemas_is_idempotent():
    first = hs.register_schemas()
    assert hs.register_schemas() == first == SCHEMAS_DIR.resolve()
    assert first.is_absolute()


def test_version():
    assert humv_usd.__version__ == "0.1.0"


def test_constants_cover_every_schema_attribute():
    """One constant per schema attribute, and every constant names a real attribute."""
    schema_props = set()
    for schema in hs.SCHEMAS:
        schema_props.update(_definition(schema).GetPropertyNames())
    constants = set(ATTRIBUTE_CONSTANTS.values())
    assert len(constants) == len(ATTRIBUTE_CONSTANTS), "two constants share a name"
    assert constants == schema_props


def test_schema_names_match_table():
    expected = {
        "HumvScenarioAPI",
        "HumvEnvironmentAPI",
        "HumvAtmosphereAPI",
        "HumvAtmospherePathAPI",
        "HumvMaterialAPI",
        "HumvAvatarAPI",
        "HumvClothingAPI",
        "HumvThermalAPI",
        "HumvSensorAPI",
        "HumvLabelAPI",
    }
    assert set(hs.SCHEMAS) == expected == set(APPLIES_TO)


@pytest.mark.parametrize(
    "prim_type, schema, attribute, expected",
    [
        ("Scope", hs.ENVIRONMENT_API, hs.ENVIRONMENT_AIR_TEMPERATURE, 293.15),
        ("Scope", hs.ENVIRONMENT_API, hs.ENVIRONMENT_RELATIVE_HUMIDITY, 0.5),
        ("Scope", hs.ENVIRONMENT_API, hs.ENVIRONMENT_PRESSURE, 101325.0),
        ("Scope", hs.ENVIRONMENT_API, hs.ENVIRONMENT_WIND_SPEED, 1.0),
        ("Scope", hs.ATMOSPHERE_API, hs.ATMOSPHERE_SKY_EMISSIVITY, 0.8),
        ("Scope", hs.ATMOSPHERE_API, hs.ATMOSPHERE_MODEL, "analytic"),
        ("Scope", hs.ATMOSPHERE_API, hs.ATMOSPHERE_PROFILE, "usStandard1976"),
        ("Scope", hs.ATMOSPHERE_API, hs.ATMOSPHERE_VISIBILITY, 23000.0),
        ("Mesh", hs.THERMAL_API, hs.THERMAL_MODEL, "fixed"),
        ("Mesh", hs.CLOTHING_API, hs.CLOTHING_MINIMUM_GAP, 0.002),
        ("Camera", hs.SENSOR_API, hs.SENSOR_BAND, "LWIR"),
        ("Camera", hs.SENSOR_API, hs.SENSOR_BIT_DEPTH, 14),
        ("Camera", hs.SENSOR_API, hs.SENSOR_NETD, 0.05),
        ("Camera", hs.SENSOR_API, hs.SENSOR_WAVELENGTH_RANGE, (8.0, 14.0)),
    ],
)
def test_apply_gives_fallbacks(prim_type, schema, attribute, expected):
    _stage, prim = _stage_with(prim_type)
    assert prim.ApplyAPI(schema)
    assert prim.HasAPI(schema)
    attr = prim.GetAttribute(attribute)
    assert attr, f"{attribute} missing after ApplyAPI({schema})"
    value = attr.Get()
    if isinstance(expected, float):
        assert value == pytest.approx(expected, rel=1e-6)
    elif isinstance(expected, tuple):
        assert tuple(value) == pytest.approx(expected)
    else:
        assert value == expected
    # Fallbacks come from the definition: nothing is authored on the stage.
    assert not attr.HasAuthoredValue()


@pytest.mark.parametrize("schema", hs.SCHEMAS)
@pytest.mark.parametrize("prim_type", PRIM_TYPES)
def test_can_apply_only_to_table_types(schema, prim_type):
    _stage, prim = _stage_with(prim_type)
    assert bool(prim.CanApplyAPI(schema)) == (prim_type in APPLIES_TO[schema])


@pytest.mark.parametrize(
    "prim_type, schema",
    [("Mesh", hs.SENSOR_API), ("Xform", hs.MATERIAL_API), ("Camera", hs.THERMAL_API)],
)
def test_can_apply_says_why_not(prim_type, schema):
    _stage, prim = _stage_with(prim_type)
    result = prim.CanApplyAPI(schema)
    assert not result
    assert "can only be applied" in result.whyNot


@pytest.mark.parametrize("attribute, tokens", sorted(ALLOWED_TOKENS.items()))
def test_token_attributes_list_allowed_tokens(attribute, tokens):
    schema = next(s for s in hs.SCHEMAS if attribute in _definition(s).GetPropertyNames())
    prim_type = sorted(APPLIES_TO[schema])[0]
    _stage, prim = _stage_with(prim_type)
    prim.ApplyAPI(schema)
    attr = prim.GetAttribute(attribute)
    assert attr.GetTypeName() == Sdf.ValueTypeNames.Token
    assert list(attr.GetMetadata("allowedTokens")) == tokens
    fallback = attr.Get()
    assert fallback is None or fallback in tokens


def test_every_token_attribute_is_checked():
    token_attrs = set()
    for schema in hs.SCHEMAS:
        definition = _definition(schema)
        for name in definition.GetPropertyNames():
            if definition.GetAttributeDefinition(name).GetTypeName() == Sdf.ValueTypeNames.Token:
                token_attrs.add(name)
    assert token_attrs == set(ALLOWED_TOKENS) | OPEN_TOKENS


def _generated_layer() -> Sdf.Layer:
    return Sdf.Layer.OpenAsAnonymous(str(SCHEMAS_DIR / "generatedSchema.usda"))


def test_generated_docs_give_units_and_range():
    layer = _generated_layer()
    assert {p.name for p in layer.rootPrims} == set(hs.SCHEMAS)
    missing = []
    for prim in layer.rootPrims:
        if not prim.documentation:
            missing.append(f"{prim.name}: no doc")
        for prop in prim.properties:
            doc = prop.documentation
            if not ("Units" in doc or "dimensionless" in doc) or "Range" not in doc:
                missing.append(f"{prop.path}: {doc!r}")
    assert not missing, "\n".join(missing)


def test_full_docs_reach_the_stage():
    """The full doc (not only usdGenSchema's first sentence) is what USD reports."""
    _stage, prim = _stage_with("Scope")
    prim.ApplyAPI(hs.ENVIRONMENT_API)
    doc = prim.GetAttribute(hs.ENVIRONMENT_AIR_TEMPERATURE).GetDocumentation()
    assert doc.endswith("Units: K. Range: 200–340.")


@pytest.mark.parametrize(
    "schema, primvar, interpolation, prim_type",
    [
        (hs.THERMAL_API, hs.TEMPERATURE_PRIMVAR, "uniform", "Mesh"),
        (hs.CLOTHING_API, hs.AIR_GAP_PRIMVAR, "vertex", "Mesh"),
    ],
)
def test_primvar_interpolation(schema, primvar, interpolation, prim_type):
    from pxr import UsdGeom

    definition = _definition(schema).GetAttributeDefinition(primvar)
    assert definition.GetTypeName() == Sdf.ValueTypeNames.FloatArray
    assert definition.GetMetadata("interpolation") == interpolation

    _stage, prim = _stage_with(prim_type)
    prim.ApplyAPI(schema)
    pv = UsdGeom.PrimvarsAPI(prim).GetPrimvar(primvar.removeprefix("primvars:"))
    assert pv and pv.GetInterpolation() == interpolation


def test_temperature_primvar_time_samples():
    _stage, prim = _stage_with("Mesh")
    prim.ApplyAPI(hs.THERMAL_API)
    attr = prim.GetAttribute(hs.TEMPERATURE_PRIMVAR)
    assert attr.Set([300.0, 301.0], 0) and attr.Set([302.0, 303.0], 1)
    assert list(attr.Get(1)) == [302.0, 303.0]


def test_plug_info_is_codeless_resource():
    import json

    text = (SCHEMAS_DIR / "plugInfo.json").read_text(encoding="utf-8")
    assert "@PLUG_INFO_" not in text
    info = json.loads("\n".join(l for l in text.splitlines() if not l.lstrip().startswith("#")))
    (plugin,) = info["Plugins"]
    assert (
        plugin["Name"],
        plugin["Type"],
        plugin["LibraryPath"],
        plugin["ResourcePath"],
        plugin["Root"],
    ) == (
        "humvUsd",
        "resource",
        "",
        ".",
        ".",
    )
    types = plugin["Info"]["Types"]
    assert set(types) == set(hs.SCHEMAS)
    for name, entry in types.items():
        assert entry["schemaIdentifier"] == name
        assert "alias" not in entry
        assert entry["schemaKind"] == "singleApplyAPI"
        assert set(entry["apiSchemaCanOnlyApplyTo"]) == APPLIES_TO[name]


def _clean_env() -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k not in ("PXR_PLUGINPATH_NAME", "HUMV_USD_SCHEMAS")}
    env.pop("PYTHONPATH", None)
    return env


def test_generated_files_up_to_date():
    proc = subprocess.run(
        [sys.executable, str(REPO / "tools" / "gen_schemas.py"), "--check"],
        cwd=REPO,
        env=_clean_env(),
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 0, proc.stderr


def test_other_usd_tools_load_schemas_through_plugin_path(tmp_path):
    """A plain pxr process finds the schemas through PXR_PLUGINPATH_NAME, without humv_usd."""
    code = (
        "import sys\n"
        "from pxr import Usd\n"
        "assert Usd.SchemaRegistry().FindAppliedAPIPrimDefinition('HumvSensorAPI') is not None\n"
        "stage = Usd.Stage.CreateInMemory()\n"
        "cam = stage.DefinePrim('/Cam', 'Camera')\n"
        "assert cam.CanApplyAPI('HumvSensorAPI') and cam.ApplyAPI('HumvSensorAPI')\n"
        "assert cam.GetAttribute('humv:sensor:bitDepth').Get() == 14\n"
        "assert not stage.DefinePrim('/M', 'Mesh').CanApplyAPI('HumvSensorAPI')\n"
        "assert 'humv_usd' not in sys.modules\n"
        "print('ok')\n"
    )
    env = _clean_env()
    env["PXR_PLUGINPATH_NAME"] = str(SCHEMAS_DIR.resolve())
    proc = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "ok"


def test_import_with_schemas_on_plugin_path_does_not_double_register(tmp_path):
    env = _clean_env()
    env["PXR_PLUGINPATH_NAME"] = str(SCHEMAS_DIR.resolve())
    proc = subprocess.run(
        [sys.executable, "-c", "import humv_usd; print(humv_usd.register_schemas())"],
        cwd=REPO,
        env=env,
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 0, proc.stderr
    assert "already registered" not in proc.stderr.lower()


def test_bad_schemas_dir_raises_clear_error(tmp_path):
    env = _clean_env()
    env["HUMV_USD_SCHEMAS"] = str(tmp_path / "nowhere")
    proc = subprocess.run(
        [sys.executable, "-c", "import humv_usd"], cwd=REPO, env=env, capture_output=True, text=True
    )
    assert proc.returncode != 0
    assert "RuntimeError: HumV-USD schemas not found" in proc.stderr
