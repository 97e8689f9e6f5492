"""Readers of the ground-truth labels on the stage: the class and instance id (HumvLabelAPI,
or a custom ``humv:label:class``) of a prim or its nearest labelled ancestor, and the per-face
body region / JOS-3 segment primvars (:mod:`humv_usd.usd.avatar` writes them).

Ground truth (:mod:`humv_usd.groundtruth.labels`) turns these into label tables; it validates
the class tokens against its class list.
"""

from __future__ import annotations

import numpy as np
from pxr import Usd, UsdGeom

from humv_usd.errors import InputError, bad_value
from humv_usd.usd import schemas as S
from humv_usd.usd.avatar import BODY_REGION_PRIMVAR, JOS3_SEGMENT_PRIMVAR

#: per-face label -> its primvar
FACE_LABELS = {"body_region": BODY_REGION_PRIMVAR, "jos3_segment": JOS3_SEGMENT_PRIMVAR}


def _has_label_api(prim: Usd.Prim) -> bool:
    return S.LABEL_API in prim.GetAppliedSchemas()


def _nearest(prim: Usd.Prim, name: str, api_fallback: bool):
    """(prim, value) of ``prim`` or its nearest ancestor that authors ``name`` (with
    ``api_fallback``: or has HumvLabelAPI, whose fallback counts); (None, None) when none."""
    p = prim
    while p and p.IsValid() and not p.IsPseudoRoot():
        attr = p.GetAttribute(name)
        if attr and (
            attr.HasAuthoredValue() or (api_fallback and _has_label_api(p) and attr.Get() is not None)
        ):
            return p, attr.Get()
        p = p.GetParent()
    return None, None


def nearest_class(prim: Usd.Prim) -> tuple[Usd.Prim | None, str | None]:
    """(the prim that says it, class token) of ``prim`` or its nearest ancestor with a class
    (``humv:label:class`` authored, or the HumvLabelAPI fallback); (None, None) when none."""
    where, value = _nearest(prim, S.LABEL_CLASS, api_fallback=True)
    return (None, None) if where is None else (where, str(value))


def class_attribute(where: Usd.Prim) -> str:
    """``<prim>.humv:label:class``: how a message names the class of ``where``."""
    return f"{where.GetPath()}.{S.LABEL_CLASS}"


#: Largest instance id (the render stores it exactly in a float32 image channel).
MAX_INSTANCE_ID = 2**24 - 1


def instance_id(prim: Usd.Prim) -> int:
    """The instance id of ``prim`` or its nearest ancestor with an authored
    ``humv:label:instanceId`` (0, the background, when none); InputError when it is not an
    integer in 0..:data:`MAX_INSTANCE_ID`."""
    where, value = _nearest(prim, S.LABEL_INSTANCE_ID, api_fallback=False)
    if where is None:
        return 0
    if value is None or not (0 <= int(value) <= MAX_INSTANCE_ID) or int(value) != value:
        raise InputError(
            bad_value(
                f"{where.GetPath()}.{S.LABEL_INSTANCE_ID}",
                value,
                f"expected an integer in 0..{MAX_INSTANCE_ID}",
            )
        )
    return int(value)


def nearest_instance_id(prim: Usd.Prim) -> tuple[Usd.Prim | None, int | None]:
    """(the prim that carries it, instance id) of ``prim`` or its nearest ancestor with an
    authored ``humv:label:instanceId``; (None, None) when none."""
    where, value = _nearest(prim, S.LABEL_INSTANCE_ID, api_fallback=False)
    return (None, None) if where is None else (where, int(value))


def read_face_label(prim: Usd.Prim, which: str, faces: int, lo: int, hi: int) -> np.ndarray | None:
    """(faces,) int32 ids of the per-face label ``which`` (:data:`FACE_LABELS`) of a mesh, None
    when not authored; InputError when there is not one id per authored face or an id is
    outside ``lo``..``hi``."""
    name = FACE_LABELS[which]
    attr = prim.GetAttribute(name)
    if not attr or not attr.HasValue():
        return None
    primvar = UsdGeom.Primvar(attr)
    values = primvar.ComputeFlattened() if primvar else attr.Get()
    a = np.asarray(values if values is not None else [], dtype=np.int64).ravel()
    where = f"{prim.GetPath()}.{name}"
    if a.size != faces:
        raise InputError(
            bad_value(
                where, f"<{a.size} values>", f"expected {faces} values (one per authored face, uniform)"
            )
        )
    if a.size and (a.min() < lo or a.max() > hi):
        raise InputError(bad_value(where, f"<range {a.min()}..{a.max()}>", f"expected ids in {lo}..{hi}"))
    return a.astype(np.int32)
