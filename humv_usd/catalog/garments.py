"""The garment catalogue: which part of MakeHuman's helper geometry each garment keeps.

MakeHuman's base mesh carries helper geometry that its macro targets deform together with the
body (so it fits every fitted body): ``helper-tights`` (a skin-tight suit over torso, arms to
the wrists, legs and feet; 2650 quads, ~6 mm off the skin) and ``helper-skirt`` (a loose tube
from the waist to the shins). MakeHuman's own clothes (MakeClothes, which the seed's HART used)
are fitted to these helpers. A garment here is one or more :class:`Part`: the faces of a source
mesh (a helper or, for the cap, the body itself) that :class:`Cover` rules keep, offset by the
garment's ease along the surface normal (:mod:`humv_usd.clothing.fit`).

Face selection. Each face gets the body region (:mod:`humv_usd.human.labels`) of the body
face nearest to its centre, and its position along a bone: ``t`` = projection of the face
centre on the bone's axis, 0 at the joint (head), 1 at the bone's tail (the child joint), in the
rest pose. A :class:`Cover` keeps faces of its regions with ``t_min <= t + tilt * y' <= t_max``
(``y'`` = depth behind the bone's head in bone lengths, + = towards the back; it tilts the cut,
e.g. a cap lower at the back than at the forehead); ``level`` covers measure ``t`` by height
instead (a level hem). Garments are cut along smooth curves, not along the source's quads
(:func:`humv_usd.clothing.fit.cut_fields`). Region names without a side
(``upperArm``, ``lowerLeg``...) and bone names without a side (``Arm``, ``UpLeg``...) apply to
both sides.

Props (:class:`Prop`, e.g. the ``rifle``) are catalogue entries too (so ``human.clothing``
selects them) but rigid: a few boxes and cylinders bound 100 % to one joint, placed in the rest
pose by :mod:`humv_usd.clothing.fit`, never pushed by the collision fix and never a layer for
another garment; the clothing layer writes them under ``/World/Humans/<id>/Props``.

Layers (``layer``, inner first) decide which garment goes over which where they overlap: the
outer one keeps at least the inner one's air gap + thickness + the minimum gap there
(:mod:`humv_usd.clothing.collide`). Fabrics are names in
:data:`humv_usd.catalog.materials.LIBRARY` (with sources there).
"""

from __future__ import annotations

from dataclasses import dataclass

from humv_usd.catalog.materials import LIBRARY

#: Default smallest skin-garment gap [m] (HumvClothingAPI ``minimumGap`` fallback).
MINIMUM_GAP = 0.002
SOURCES = ("tights", "skirt", "body")

#: Side-less region names -> the two sided names of :data:`humv_usd.human.labels.BODY_REGIONS`.
SIDED_REGIONS = ("upperArm", "lowerArm", "hand", "upperLeg", "lowerLeg", "foot")
#: Side-less limb bone names -> (left, right) joints of the CMU rig.
SIDED_BONES = {
    "Arm": ("LeftArm", "RightArm"),
    "ForeArm": ("LeftForeArm", "RightForeArm"),
    "UpLeg": ("LeftUpLeg", "RightUpLeg"),
    "Leg": ("LeftLeg", "RightLeg"),
    "Foot": ("LeftFoot", "RightFoot"),
}
TORSO = ("chest", "abdomen", "back")


@dataclass(frozen=True)
class Cover:
    """Faces of ``regions`` whose position along ``bone`` is within [t_min, t_max]."""

    regions: tuple[str, ...]
    bone: str | None = None
    t_min: float = float("-inf")
    t_max: float = float("inf")
    tilt: float = 0.0
    #: measure the position by height instead: t = (z - z_head) / (z_tail - z_head) in the rest
    #: pose, so the cut is level (a hem), not square to a tilted bone
    level: bool = False


@dataclass(frozen=True)
class Part:
    """Faces of one source mesh, offset by ``ease`` [m] along the surface normal.

    ``loose``: skin weights smoothed over the part and blended towards the pelvis (a skirt
    that swings as one piece instead of splitting with the legs; see ``fit``).
    """

    source: str
    cover: tuple[Cover, ...]
    ease: float
    loose: bool = False


@dataclass(frozen=True)
class Shape:
    """A box (``radius`` 0: ``size`` = x, y, z edge lengths) or a cylinder along x (``size``
    = (length, -, -), ``radius`` > 0) centred at ``centre``, in the prop's frame [m]."""

    name: str
    centre: tuple[float, float, float]
    size: tuple[float, float, float]
    radius: float = 0.0


@dataclass(frozen=True)
class Prop:
    """A rigid prop: ``shapes`` in its own frame (x: length axis, z: up), bound 100 % to
    ``joint``; ``placement`` names the rule :mod:`humv_usd.clothing.fit` places it by."""

    shapes: tuple[Shape, ...]
    joint: str
    placement: str
    #: a prop held in the hand: (contact point, outward surface normal there, the direction the
    #: fingers run along it), in the prop's frame: the palm lies on the prop at the contact point
    #: (:func:`humv_usd.human.carry.held_rest_transform`)
    grip: tuple[tuple[float, float, float], tuple[float, float, float], tuple[float, float, float]] | None = (
        None
    )


@dataclass(frozen=True)
class Garment:
    name: str
    description: str
    parts: tuple[Part, ...]
    fabric: str  # material name in the library
    layer: int  # 0 = next to the skin; higher goes over lower
    minimum_gap: float = MINIMUM_GAP
    prop: Prop | None = None  # a rigid prop instead of fitted parts
    #: part of the body for the garments over it: they are also pushed out of its posed
    #: surface (thickness + their minimum gap), not only by the layer correspondence
    body_like: bool = False

    @property
    def ease(self) -> float:
        """The design ease [m] (of the first part; HumvClothingAPI ``ease``); 0 for props."""
        return self.parts[0].ease if self.parts else 0.0

    @property
    def is_prop(self) -> bool:
        return self.prop is not None

    @property
    def thickness(self) -> float:
        """Fabric thickness [m] (from the fabric's library entry)."""
        return LIBRARY[self.fabric].thickness


def _arms(t_max_upper: float | None, t_max_lower: float | None = None) -> tuple[Cover, ...]:
    """Sleeves: the upper arm down to ``t_max_upper`` of the humerus, or the whole upper arm
    and the forearm down to ``t_max_lower``."""
    if t_max_lower is None:
        return (Cover(("upperArm",), "Arm", t_max=t_max_upper),)
    return (Cover(("upperArm",)), Cover(("lowerArm",), "ForeArm", t_max=t_max_lower))


# Hem heights along the Hips bone (0 = hip joints' height, 1 = waist, the LowerBack joint).
_TSHIRT_HEM = -0.4
_JACKET_HEM = -0.9  # the crotch is at -1.15 (men) .. -1.45 (women)

_VEST_HEM = 0.5  # carrier ends half way between the hip joints and the waist
_TOP = TORSO


def _hem(t_min: float) -> Cover:
    """The trunk above a level hem at height ``t_min`` of the Hips bone: one cut across every
    region (torso, pelvis and the tops of the thighs at the groin and the hip sides). The Hips
    bone leans back ~20 deg, so a cut square to it was 7 cm higher at the front than at the back;
    cut on the pelvis alone, it met the thighs' region border at the groin and left notches."""
    return Cover(_TOP + ("pelvis", "upperLeg"), "Hips", t_min=t_min, level=True)


#: Layer of props: after every garment (they are never under one).
PROP_LAYER = 9

#: An assault-rifle-sized prop (M4-like proportions), 0.90 m from butt to muzzle; x towards
#: the muzzle, origin at the pistol grip's top.
RIFLE = Prop(
    (
        Shape("stock", (-0.16, 0.0, -0.015), (0.28, 0.040, 0.10)),
        Shape("receiver", (0.10, 0.0, 0.010), (0.24, 0.050, 0.08)),
        Shape("grip", (0.005, 0.0, -0.080), (0.040, 0.030, 0.10)),
        Shape("magazine", (0.100, 0.0, -0.125), (0.070, 0.030, 0.19)),
        Shape("handguard", (0.32, 0.0, 0.015), (0.20, 0.0, 0.0), radius=0.024),
        Shape("barrel", (0.51, 0.0, 0.015), (0.18, 0.0, 0.0), radius=0.008),
    ),
    joint="RightHand",
    placement="between_hands",
)
_TROUSER_TOP = (Cover(("pelvis",)),)

#: A second long gun: a pump shotgun (wooden stock and forend, 1.0 m), held like the rifle:
#: same frame (x to the muzzle, origin at the grip's top), the grip and the forend where the
#: rifle carry puts the hands (:mod:`humv_usd.human.carry`: grip at the origin, the left hand
#: on the x axis 0.2-0.4 m ahead), so the carry fits it as it fits the rifle.
SHOTGUN = Prop(
    (
        Shape("stock", (-0.20, 0.0, -0.03), (0.34, 0.038, 0.11)),
        Shape("grip", (0.0, 0.0, -0.05), (0.06, 0.030, 0.08)),
        Shape("receiver", (0.10, 0.0, 0.005), (0.18, 0.036, 0.06)),
        Shape("forend", (0.32, 0.0, 0.0), (0.22, 0.0, 0.0), radius=0.022),
        Shape("magazine_tube", (0.43, 0.0, -0.012), (0.28, 0.0, 0.0), radius=0.011),
        Shape("barrel", (0.52, 0.0, 0.016), (0.66, 0.0, 0.0), radius=0.0105),
    ),
    joint="RightHand",
    placement="between_hands",
)
#: A daypack (30 l): body against the upper back, rigid on Spine1. Frame: origin at the centre
#: of the face that touches the back, +y away from the back, z up (placement "on_back").
BACKPACK = Prop(
    (
        Shape("pack", (0.0, 0.09, 0.0), (0.30, 0.18, 0.45)),
        Shape("front_pocket", (0.0, 0.20, -0.08), (0.24, 0.04, 0.20)),
    ),
    joint="Spine1",
    placement="on_back",
)
#: A shoulder bag at the left hip, rigid on the Hips. Frame: origin at the centre of the face
#: that touches the hip, +x away from it (placement "at_left_hip").
BAG = Prop((Shape("bag", (0.045, 0.0, 0.0), (0.09, 0.28, 0.22)),), joint="Hips", placement="at_left_hip")
#: A smartphone (147 x 72 x 8 mm) held in the right hand, rigid on the RightHand: its back (-x
#: face) on the palm, the fingers along its length towards the top (+z), the palm's grasp point
#: 5 cm below its centre. Placement "held_front": read in front of the chest
#: (:func:`humv_usd.human.carry.apply_hold` poses the right arm); "held_ear" (``phone_call``):
#: at the right ear, screen against the cheek.
_PHONE_SHAPES = (Shape("phone", (0.0, 0.0, 0.0), (0.008, 0.072, 0.147)),)
_PHONE_GRIP = ((-0.004, 0.0, -0.05), (-1.0, 0.0, 0.0), (0.0, 0.0, 1.0))
PHONE = Prop(_PHONE_SHAPES, joint="RightHand", placement="held_front", grip=_PHONE_GRIP)
PHONE_CALL = Prop(_PHONE_SHAPES, joint="RightHand", placement="held_ear", grip=_PHONE_GRIP)
#: A handbag carried by its handle in the right hand, arm hanging (placement "by_handle"):
#: frame origin at the handle's centre, x along the handle, z up. The handle (a flat leather
#: strap 14 cm x 20 mm x 8 mm) lies across the palm at the grasp point (its -y face on the
#: palm); two straps run from its ends, beside the hand, down to the bag (34 x 12 x 28 cm),
#: whose top is 20 cm below the handle, below the fingertips of an adult hand.
HANDBAG_DROP = 0.20
HANDBAG = Prop(
    (
        Shape("handle", (0.0, 0.0, 0.0), (0.14, 0.008, 0.020)),
        Shape("strap_front", (-0.074, 0.0, -HANDBAG_DROP / 2), (0.008, 0.008, HANDBAG_DROP + 0.02)),
        Shape("strap_back", (0.074, 0.0, -HANDBAG_DROP / 2), (0.008, 0.008, HANDBAG_DROP + 0.02)),
        Shape("bag", (0.0, 0.0, -HANDBAG_DROP - 0.14), (0.34, 0.12, 0.28)),
    ),
    joint="RightHand",
    placement="by_handle",
    grip=((0.0, -0.004, 0.0), (0.0, -1.0, 0.0), (0.0, 0.0, -1.0)),
)
#: Glasses: two lenses, a bridge and two temples, rigid on the Head (placement "on_face":
#: the lenses 12 mm in front of the eyes, the temples along the sides of the head). Frame:
#: origin between the eyes, x to the person's left, -y forward, z up; the temples' x and
#: length are set per head by the placement.
GLASSES = Prop(
    (
        Shape("left_lens", (0.032, 0.0, 0.0), (0.050, 0.003, 0.036)),
        Shape("right_lens", (-0.032, 0.0, 0.0), (0.050, 0.003, 0.036)),
        Shape("bridge", (0.0, 0.0, 0.008), (0.016, 0.003, 0.004)),
        Shape("left_temple", (0.062, 0.05, 0.008), (0.003, 0.10, 0.004)),
        Shape("right_temple", (-0.062, 0.05, 0.008), (0.003, 0.10, 0.004)),
    ),
    joint="Head",
    placement="on_face",
)


def _catalogue() -> dict[str, Garment]:
    tshirt_cover = (_hem(_TSHIRT_HEM),) + _arms(0.45)
    longsleeve_cover = (_hem(_TSHIRT_HEM),) + _arms(None, 0.93)
    jacket_cover = (
        _hem(_JACKET_HEM),
        Cover(("neck",), "Neck", t_max=0.6),
    ) + _arms(None, 0.95)
    shorts_cover = _TROUSER_TOP + (Cover(("upperLeg",), "UpLeg", t_max=0.5),)
    legs_cover = _TROUSER_TOP + (Cover(("upperLeg",)), Cover(("lowerLeg",), "Leg", t_max=0.93))
    trouser_cover = _TROUSER_TOP + (Cover(("upperLeg",)), Cover(("lowerLeg",), "Leg", t_max=0.96))
    garments = (
        Garment(
            "tshirt_white",
            "white cotton T-shirt: torso to the hip joints, sleeves to mid upper arm",
            (Part("tights", tshirt_cover, 0.008),),
            "cotton_white",
            2,
        ),
        Garment(
            "tshirt_black",
            "black cotton T-shirt (same cut as tshirt_white)",
            (Part("tights", tshirt_cover, 0.008),),
            "cotton_black",
            2,
        ),
        Garment(
            "longsleeve",
            "grey polyester long-sleeved shirt: torso to the hip joints, sleeves to the wrists",
            (Part("tights", longsleeve_cover, 0.008),),
            "polyester",
            2,
        ),
        Garment(
            "shorts",
            "grey polyester shorts: waist to mid thigh",
            (Part("tights", shorts_cover, 0.010),),
            "polyester",
            1,
        ),
        Garment(
            "leggings",
            "black nylon/elastane leggings: waist to the ankles",
            (Part("tights", legs_cover, 0.001),),
            "nylon",
            0,
        ),
        Garment(
            "trousers",
            "black cotton trousers: waist to the ankles",
            (Part("tights", trouser_cover, 0.012),),
            "cotton_black",
            1,
        ),
        Garment(
            "jacket",
            "military uniform jacket (NYCO camouflage): torso to below the "
            "hips, stand-up collar, sleeves to the wrists",
            (Part("tights", jacket_cover, 0.015),),
            "camouflage_nyco",
            3,
        ),
        Garment(
            "uniform_trousers",
            "military uniform trousers (NYCO camouflage): waist to the ankles",
            (Part("tights", trouser_cover, 0.015),),
            "camouflage_nyco",
            1,
        ),
        Garment(
            "robe",
            "loose white cotton robe: long-sleeved top over a skirt from the waist to the shins",
            (Part("tights", (Cover(_TOP),) + _arms(None, 0.93), 0.020), Part("skirt", (), 0.006, loose=True)),
            "cotton_white",
            3,
        ),
        Garment(
            "vest",
            "soft body armour carrier worn under the clothing: close-fitting, "
            "no sleeves, torso from above the hips to the neckline (part of the body for "
            "the garments over it)",
            (Part("tights", (_hem(_VEST_HEM),), 0.004),),
            "kevlar_vest",
            1,
            body_like=True,
        ),
        Garment(
            "rifle",
            "rifle prop (stock, receiver, grip, magazine, handguard, barrel; "
            "0.90 m) held across the body between the hands, rigidly bound to the right "
            "hand",
            (),
            "polymer_black",
            PROP_LAYER,
            prop=RIFLE,
        ),
        Garment(
            "shoes",
            "black leather shoes: the feet up to the ankles (one shell over the foot, sole included)",
            (Part("tights", (Cover(("foot",)),), 0.0),),
            "leather_black",
            2,
        ),
        Garment(
            "boots",
            "black rubber boots: the feet and the lower shins",
            (Part("tights", (Cover(("foot",)), Cover(("lowerLeg",), "Leg", t_min=0.6)), 0.001),),
            "rubber_black",
            2,
        ),
        Garment(
            "jeans",
            "indigo denim jeans: waist to the ankles, close-fitting",
            (Part("tights", trouser_cover, 0.002),),
            "denim",
            1,
        ),
        Garment(
            "sweater",
            "navy thick wool sweater: torso to the hip joints, sleeves to the wrists",
            (Part("tights", longsleeve_cover, 0.004),),
            "wool_knit_thick",
            3,
        ),
        Garment(
            "fleece_jacket",
            "olive polyester fleece jacket (4 mm pile): torso to below the hips, stand-up "
            "collar, sleeves to the wrists",
            (Part("tights", jacket_cover, 0.006),),
            "fleece",
            3,
        ),
        Garment(
            "winter_coat",
            "black down-filled winter coat (12 mm loft): torso to below the hips, collar, "
            "sleeves to the wrists; goes over a jacket, fleece or sweater",
            (Part("tights", jacket_cover, 0.010),),
            "down_fill",
            4,
        ),
        Garment(
            "hair_short",
            "short dark head hair: a 5 mm fibre layer over the skull above the brow and the "
            "back of the head (under a cap)",
            (Part("body", (Cover(("head",), "Head", t_min=0.45, tilt=0.5),), 0.001),),
            "hair_dark",
            0,
        ),
        Garment(
            "cap",
            "charcoal wool knit cap: the skull above the brow, ears free",
            (Part("body", (Cover(("head",), "Head", t_min=0.5, tilt=0.4),), 0.003),),
            "wool",
            1,
        ),
        # ---- issue 29: hair styles (MakeHuman's CC0 helper-hair proxy and the body's scalp,
        # face and neck) with the thermal hair layer of hair_short
        Garment(
            "hair_long",
            "long dark hair: MakeHuman's long-hair proxy (helper-hair: over the skull and down "
            "the back to the shoulder blades), a 5 mm fibre layer over the clothing (layer 4: "
            "under a coat, a beanie or a helmet; over a cap or a hood)",
            (Part("hair", (), 0.004),),
            "hair_dark",
            4,
        ),
        Garment(
            "hair_tied",
            "dark hair tied back: the short scalp layer plus a tail down the nape (the neck part "
            "of the long-hair proxy)",
            (
                Part("body", (Cover(("head",), "Head", t_min=0.45, tilt=0.5),), 0.001),
                Part("hair", (Cover(("neck",)),), 0.006),
            ),
            "hair_dark",
            0,
        ),
        Garment(
            "beard",
            "full dark beard: chin, jaw, cheeks below the mouth corners and the upper throat, a 5 mm "
            "fibre layer",
            (
                Part(
                    "body",
                    (Cover(("face",), "Head", t_max=-0.1), Cover(("neck",), "Neck", t_min=0.6, tilt=-1.0)),
                    0.001,
                ),
            ),
            "hair_dark",
            0,
        ),
        # ---- issue 29: the wardrobe
        Garment(
            "dress",
            "grey polyester dress: fitted top with short sleeves over a skirt from the waist to the shins",
            (Part("tights", (Cover(_TOP),) + _arms(0.35), 0.006), Part("skirt", (), 0.006, loose=True)),
            "polyester",
            2,
        ),
        Garment(
            "skirt",
            "indigo denim skirt: waist to the shins, loose (swings with the thighs)",
            (Part("skirt", (), 0.008, loose=True),),
            "denim",
            2,
        ),
        Garment(
            "hoodie",
            "black cotton hooded sweatshirt: torso to below the hips, sleeves to the wrists, "
            "hood up over the back and top of the head",
            (
                Part(
                    "tights",
                    (_hem(_JACKET_HEM),) + _arms(None, 0.95),
                    0.010,
                ),
                Part("body", (Cover(("head",), "Head", t_min=0.1, tilt=0.8),), 0.022),
            ),
            "cotton_black",
            3,
        ),
        Garment(
            "gloves",
            "black leather gloves: the hands and wrists",
            (Part("body", (Cover(("hand",)), Cover(("lowerArm",), "ForeArm", t_min=0.9)), 0.002),),
            "leather_black",
            2,
        ),
        Garment(
            "scarf",
            "charcoal wool scarf wound round the neck (12 mm off the skin, over a collar)",
            (Part("body", (Cover(("neck",)),), 0.024),),
            "wool",
            5,
        ),
        Garment(
            "beanie",
            "navy thick-knit beanie: the skull down over the ears",
            (Part("body", (Cover(("head",), "Head", t_min=0.35, tilt=0.4),), 0.004),),
            "wool_knit_thick",
            6,
        ),
        Garment(
            "helmet",
            "combat helmet (aramid composite shell, ACH-like, 8 mm) standing 2 cm off the "
            "skull above the brow and ears",
            (Part("body", (Cover(("head",), "Head", t_min=0.4, tilt=0.4),), 0.02),),
            "kevlar_vest",
            6,
        ),
        Garment(
            "socks",
            "white cotton socks: the feet and the ankles (under shoes or boots)",
            (Part("tights", (Cover(("foot",)), Cover(("lowerLeg",), "Leg", t_min=0.75)), 0.0),),
            "cotton_white",
            1,
        ),
        Garment(
            "shotgun",
            "pump shotgun prop (wooden stock and forend, 1.0 m) held across the body like the rifle",
            (),
            "wood",
            PROP_LAYER,
            prop=SHOTGUN,
        ),
        Garment(
            "backpack",
            "black nylon daypack (30 l, 30 x 18 x 45 cm) on the upper back",
            (),
            "nylon",
            PROP_LAYER,
            prop=BACKPACK,
        ),
        Garment(
            "bag",
            "black leather shoulder bag (28 x 9 x 22 cm) at the left hip",
            (),
            "leather_black",
            PROP_LAYER,
            prop=BAG,
        ),
        Garment(
            "phone",
            "smartphone (147 x 72 x 8 mm, black polymer) read in the right hand in front of the chest",
            (),
            "polymer_black",
            PROP_LAYER,
            prop=PHONE,
        ),
        Garment(
            "phone_call",
            "smartphone (147 x 72 x 8 mm, black polymer) held at the right ear in the right hand",
            (),
            "polymer_black",
            PROP_LAYER,
            prop=PHONE_CALL,
        ),
        Garment(
            "handbag",
            "black leather handbag (34 x 12 x 28 cm) carried by its handle in the right hand",
            (),
            "leather_black",
            PROP_LAYER,
            prop=HANDBAG,
        ),
        Garment(
            "glasses",
            "glasses with black polymer frames (lenses as frame material: glass is opaque in the "
            "thermal infrared)",
            (),
            "polymer_black",
            PROP_LAYER,
            prop=GLASSES,
        ),
    )
    return {g.name: g for g in garments}


GARMENTS: dict[str, Garment] = _catalogue()
#: Props carried in both hands in the rifle carry (humv_usd.human.carry): the arms' pose
#: changes when one is worn.
LONG_GUNS = ("rifle", "shotgun")
#: Props held in the right hand that pose the right arm (humv_usd.human.carry.apply_hold); a
#: person holds at most one of these or a long gun.
HELD_PROPS = ("phone", "phone_call", "handbag")
#: Head and face hair (fabric ``hair_dark`` and its colours): a person's default clothing is
#: one of these (:func:`humv_usd.scenario.load.default_hair`), and the thermal tool gives a
#: wardrobe of hair alone its own cheaper q_rad path (:mod:`humv_usd.thermal.human`).
HAIR_GARMENTS = ("hair_short", "hair_long", "hair_tied", "beard")
#: Convenience aliases accepted by :func:`garment`.
ALIASES = {"tshirt": "tshirt_white", "t-shirt": "tshirt_white"}
#: The seed's Table 1 clothing options (HumV paper, sec. 4.1) as garment lists.
OUTFITS = {
    "bare_upper_body_shorts": ("shorts",),
    "white_shirt_shorts": ("tshirt_white", "shorts"),
    "black_shirt_shorts": ("tshirt_black", "shorts"),
    "white_shirt_leggings": ("tshirt_white", "leggings"),
    "black_shirt_leggings": ("tshirt_black", "leggings"),
    "military_uniform": ("uniform_trousers", "jacket"),
    "robe": ("robe",),
}


def garment(name: str) -> Garment:
    """A catalogue garment by name (or alias); ValueError names the known ones."""
    key = ALIASES.get(name, name)
    try:
        return GARMENTS[key]
    except KeyError:
        raise ValueError(f"unknown garment {name!r}; known: {', '.join(GARMENTS)}") from None


def fabrics(names) -> list[str]:
    """Library material names the garments ``names`` need (sorted, unique), e.g. for the
    materials layer."""
    return sorted({garment(n).fabric for n in names})
