"""Camera viewpoint presets: where the cameras of public thermal datasets stand relative to the
people they see, as distributions for the sweep's camera sampler (:mod:`humv_usd.sweep.cameras`).

Each preset gives the sensor (a :mod:`humv_usd.catalog.sensors` preset and the image size the
dataset publishes), the distributions of the camera's ground distance to the person, its height
above the ground, its azimuth around the person, its pitch (None: the camera aims at the person)
with an aim offset that spreads people over the image, and its roll; the smallest person height
[px] the dataset annotates; and what the dataset publishes about its people's pixel heights.
``source`` says, value by value, what comes from the dataset's paper or documentation and what is
our estimate from the dataset's published example images (marked "estimated").

``distance_m = None`` (with a pitch): the person is placed at a drawn offset within the central
80 % of the vertical field of view from the optical axis, and the distance follows from the height.

A distribution is ``("uniform", lo, hi)``, ``("normal", mean, sd)`` (truncated to ``clip``
when given as a fourth element ``(lo, hi)``) or ``("fixed", value)``.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class ViewpointPreset:
    name: str
    description: str
    sensor: dict  # scenario sensor keys the preset sets (preset name, resolution, pitch)
    distance_m: tuple | None  # horizontal distance camera -> person; None: from the pitch
    height_m: tuple  # camera height above the ground
    azimuth_deg: tuple  # compass azimuth of the camera seen from the person
    pitch_deg: tuple | None  # camera elevation; None: aimed at the person
    yaw_offset_deg: tuple  # horizontal aim offset from the person [deg]
    roll_deg: tuple
    min_height_px: float  # smallest person height kept [px]
    published_height_px: str  # what the dataset publishes about person heights
    published_bins_px: tuple = ()  # (edges [px], fractions) when the dataset gives a histogram
    #: (edges [px^2], fractions) of the person boxes' area when the dataset bins areas instead
    published_area_bins_px2: tuple = ()
    source: str = ""


FULL_CIRCLE = ("uniform", 0.0, 360.0)

VIEWPOINTS: dict[str, ViewpointPreset] = {
    p.name: p
    for p in (
        ViewpointPreset(
            name="flir_adas",
            description="FLIR ADAS (Teledyne FLIR free thermal dataset): a forward-looking Tau 2 "
            "640x512 on a car driving city streets and highways",
            sensor={"preset": "tau2_640"},
            distance_m=("uniform", 6.0, 70.0),
            height_m=("uniform", 1.4, 1.9),
            azimuth_deg=FULL_CIRCLE,
            pitch_deg=("normal", 0.0, 1.5, (-5.0, 5.0)),
            yaw_offset_deg=("uniform", -20.0, 20.0),
            roll_deg=("normal", 0.0, 0.5, (-2.0, 2.0)),
            min_height_px=10.0,
            published_height_px="no histogram published; people 10-250 px tall in the 512-row "
            "frames of the example images, most under 60 px (estimated)",
            source="camera: FLIR Tau 2, 640x512, 13 mm, HFOV 45 deg, on a vehicle (FLIR ADAS dataset "
            "description, v1 2018 and v2 2022; from memory, not re-checked here); mount height 1.4-1.9 "
            "m (a roof or dashboard mount), level pitch, distances 6-70 m: estimated from the example "
            "images",
        ),
        ViewpointPreset(
            name="kaist",
            description="KAIST multispectral pedestrian benchmark: a beam-splitter colour + thermal "
            "rig on a car roof, 640x512 aligned thermal images of urban and campus streets",
            sensor={"preset": "tau2_640"},
            distance_m=("uniform", 10.0, 35.0),
            height_m=("uniform", 1.8, 2.2),
            azimuth_deg=FULL_CIRCLE,
            pitch_deg=("normal", 0.0, 1.0, (-4.0, 4.0)),
            yaw_offset_deg=("uniform", -20.0, 20.0),
            roll_deg=("normal", 0.0, 0.5, (-2.0, 2.0)),
            min_height_px=20.0,
            published_height_px="scales: near >= 115 px (about 11 m and closer), medium 45-115 px, "
            "far < 45 px (about 28 m and farther); the test set's 4,254 person boxes: 28.2 % far, "
            "64.9 % medium, 6.9 % near, median 52 px",
            published_bins_px=((0.0, 45.0, 115.0, 1.0e4), (0.2821, 0.6486, 0.0693)),
            source="Hwang et al. 2015, 'Multispectral pedestrian detection: benchmark dataset and "
            "baseline', CVPR, sect. 3 (scale definitions near/medium/far and their distances; from "
            "memory, not re-checked here). Bin fractions: the test set (set06-set11, every 20th frame, "
            "2,252 images) with the improved annotations of Liu et al. 2016 ('Multispectral deep neural "
            "networks for pedestrian detection', BMVC), as the benchmark's evaluation file "
            "KAIST_annotation.json (MLPD/INSANet evaluation scripts; the copy read is "
            "github.com/chanchanchan97/ICAFusion evaluation_script/KAIST_annotation.json, commit "
            "7b16739): 1,200 / 2,759 / 295 of 4,254 person boxes far / medium / near (3,390 not "
            "flagged ignore: 24.6 / 67.7 / 7.7 %). The thermal camera is a FLIR A35 (320x256 upsampled "
            "to 640x512 in the aligned images): modelled by the Tau 2 640x512 preset at the same "
            "45 x 37 deg field (an approximation, estimated); roof height 1.8-2.2 m estimated; the "
            "distance range 10-35 m is fitted to the published bins (5-45 m gave 39 / 46 / 15 %, total "
            "variation distance 0.19; 10-35 m: 23 / 68 / 9 %, 0.06; python -m humv_usd.bench.viewpoints)",
        ),
        ViewpointPreset(
            name="llvip",
            description="LLVIP: a binocular visible + infrared surveillance camera looking down "
            "on streets at night, 1280x1024 infrared images",
            sensor={"preset": "tau2_640", "resolution": [1280, 1024], "pixel_pitch_um": 8.5},
            distance_m=("uniform", 8.0, 30.0),
            height_m=("uniform", 5.0, 9.0),
            azimuth_deg=FULL_CIRCLE,
            pitch_deg=None,
            yaw_offset_deg=("uniform", -15.0, 15.0),
            roll_deg=("normal", 0.0, 0.5, (-2.0, 2.0)),
            min_height_px=30.0,
            published_height_px="no histogram published; pedestrians 80-400 px tall in the "
            "1024-row frames of the example images (estimated)",
            source="Jia et al. 2021, 'LLVIP: a visible-infrared paired dataset for low-light vision', "
            "ICCV workshops: 1280x1024 infrared images from a HIKVISION binocular camera mounted high "
            "on a street (from memory, not re-checked here); camera height 5-9 m, distances 8-30 m and "
            "the 45 deg field: estimated from the example images",
        ),
        ViewpointPreset(
            name="ltd",
            description="LTD (Seasons in Drift, long-term thermal dataset): a fixed AXIS thermal "
            "camera above a harbour promenade, 384x288",
            sensor={"preset": "tau2_640", "resolution": [384, 288], "pixel_pitch_um": 28.3},
            distance_m=("uniform", 10.0, 60.0),
            height_m=("uniform", 4.0, 8.0),
            azimuth_deg=("uniform", 150.0, 210.0),
            pitch_deg=("uniform", -20.0, -10.0),
            yaw_offset_deg=("uniform", -25.0, 25.0),
            roll_deg=("fixed", 0.0),
            min_height_px=4.0,
            published_height_px="no height histogram published; box areas of the 5,841,139 human "
            "boxes (all 1,689 clips): 96.96 % small (< 1,024 px^2), 0.01 % medium, 3.03 % large "
            "(> 9,696 px^2)",
            published_area_bins_px2=((0.0, 1024.0, 9696.0, 1.0e9), (0.9696, 0.0001, 0.0303)),
            source="Nikolov et al. 2021, 'Seasons in Drift: a long-term thermal imaging dataset for "
            "studying concept drift', NeurIPS Datasets and Benchmarks: AXIS Q1921 thermal camera, "
            "384x288, one fixed view of a harbour front over 8 months (from memory, not re-checked "
            "here); mount height 4-8 m, a fixed view (azimuth within +-30 deg), pitch -10..-20 deg, "
            "distances 10-60 m, the 45 deg field: estimated. Box areas: the dataset statistics of the "
            "ChaLearn LAP 2022 Seasons in Drift challenge (ECCV 2022 workshops; LTD extended to 1,689 "
            "2-minute clips at 1 fps, 14 May 2020 - 30 April 2021, subset 'Full-All'), size groups "
            "small < 1,024, medium 1,025-9,695, large > 9,696 px^2: human 5,663,804 / 454 / 176,881 of "
            "5,841,139 boxes, as reproduced in github.com/phlong3105/mon docs/challenges/chalearn/"
            "chalearn22_ltd.md (commit 307cb75; the challenge page's own copy not re-checked here). "
            "The near-empty medium group beside a 3 % large one is as published (a gap no camera "
            "geometry gives: likely the grouping or a few very large boxes; not modelled). The preset "
            "was not fitted to it: 200-1,000 draws give 89-95 % small, 5-11 % medium, 0 % large, "
            "total variation distance 0.05-0.11 (python -m humv_usd.bench.viewpoints)",
        ),
        ViewpointPreset(
            name="hit_uav",
            description="HIT-UAV: a drone's thermal camera at 60-130 m over schools, parking lots, "
            "roads and playgrounds, 640x512",
            sensor={"preset": "tau2_640", "focal_length_mm": 25.0},
            distance_m=None,
            height_m=("normal", 60.0, 15.0, (60.0, 130.0)),
            azimuth_deg=FULL_CIRCLE,
            pitch_deg=("uniform", -90.0, -30.0),
            yaw_offset_deg=("uniform", -20.0, 20.0),
            roll_deg=("fixed", 0.0),
            min_height_px=2.0,
            published_height_px="12,312 person boxes: height 3-73 px, mean 21 px, median 20 px, "
            "p10-p90 15-29 px (dataset-ninja's statistics of the authors' annotations)",
            published_bins_px=(
                (0.0, 8.0, 12.0, 16.0, 20.0, 25.0, 30.0, 40.0, 80.0),
                (0.0011, 0.0167, 0.1253, 0.3035, 0.3147, 0.1545, 0.0824, 0.0017),
            ),
            source="Suo et al. 2023, 'HIT-UAV: a high-altitude infrared thermal dataset for unmanned "
            "aerial vehicle-based object detection', Scientific Data 10:227, doi:10.1038/s41597-023-"
            "02066-6 (altitude 60-130 m and camera perspective 30-90 deg, 640x512 images). Person box "
            "heights: the per-object table of github.com/dataset-ninja/hit-uav stats/object_sizes.json "
            "(Supervisely Dataset Ninja, computed from the authors' standard-box annotations; 12,312 "
            "person boxes in 1,691 images; stats/class_sizes.json: mean 21 px), binned here; their image "
            "names (<day/night>_<altitude>_<perspective>_...) give the person-weighted altitude, 51 % at "
            "60 m and the rest spread to 130 m (modelled as a normal of mean 60 m and sd 15 m truncated to "
            "60-130 m, estimated). The camera: a Tau 2 640 core (DJI Zenmuse XT2, from memory, not "
            "re-checked); the paper states no lens: 25 mm (HFOV 25 deg, the XT2's longest option) is "
            "chosen because it reproduces the published median box height (20 px; 13 mm gave 8 px, "
            "total variation distance 0.89 -> 0.13-0.16 over 300-1,000 draws, python -m "
            "humv_usd.bench.viewpoints). The ground distance follows from the pitch (the person must be "
            "in view)",
        ),
    )
}


def viewpoint(name: str) -> ViewpointPreset:
    """The viewpoint preset ``name``; KeyError naming the known ones."""
    try:
        return VIEWPOINTS[name]
    except KeyError:
        raise KeyError(f"unknown viewpoint preset {name!r}; known: {', '.join(VIEWPOINTS)}") from None
