"""Ground truth and dataset outputs: per-pixel labels, per-object boxes and keypoints, COCO JSON,
per-body-region statistics (the seed's Table 2). See docs/architecture.md "Ground truth".

Modules: :mod:`.annotators` (what runs), :mod:`.labels` (per-face tables, per-pixel images,
colour masks), :mod:`.camera` (pinhole projection), :mod:`.boxes`, :mod:`.keypoints`,
:mod:`.coco`, :mod:`.regions`, :mod:`.annotate` (the render's per-image step).
"""
from humv_usd.groundtruth.annotators import ANNOTATORS, DEFAULT_ANNOTATORS

__all__ = ["ANNOTATORS", "CHANNELS", "DEFAULT_ANNOTATORS", "GroundTruth", "ImageTruth"]


def __getattr__(name):  # lazy: annotate imports humv_usd.render, which imports this package
    if name in ("GroundTruth", "ImageTruth", "CHANNELS"):
        from humv_usd.groundtruth import annotate
        return getattr(annotate, name)
    raise AttributeError(name)
