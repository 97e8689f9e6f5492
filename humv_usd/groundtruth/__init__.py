"""Ground truth and dataset outputs: per-pixel labels, per-object boxes and keypoints, COCO JSON,
per-body-region statistics (the seed's Table 2). See docs/architecture.md "Ground truth".

Modules: :mod:`.annotators` (what runs), :mod:`.labels` (per-face tables, per-pixel images,
colour masks), :mod:`.boxes`, :mod:`.keypoints`, :mod:`.coco`, :mod:`.regions`,
:mod:`.annotate` (the render's per-image step). The pinhole camera is
:mod:`humv_usd.geometry.camera`. Ground truth consumes the render's ray casts through a small
interface (``hits``/``cast``); it does not import ``humv_usd.render``.
"""

from humv_usd.groundtruth.annotate import CHANNELS, GroundTruth, ImageTruth
from humv_usd.groundtruth.annotators import ANNOTATORS, DEFAULT_ANNOTATORS

__all__ = ["ANNOTATORS", "CHANNELS", "DEFAULT_ANNOTATORS", "GroundTruth", "ImageTruth"]
