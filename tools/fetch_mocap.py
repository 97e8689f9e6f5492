"""Fetch DeepMimic's humanoid motion clips from pybullet's source distribution and convert them.

pybullet 3.2.7's sdist (PyPI, checked against a pinned SHA-256, platform independent) carries the
clips of Peng et al. (2018) under ``examples/pybullet/gym/pybullet_data/data/motions`` (zlib
licence; the licence check is in :mod:`humv_usd.human.deepmimic`). Only the clips named in
``deepmimic.CLIPS``, the humanoid's URDF and pybullet's LICENSE.txt are unpacked; each clip is
converted to a CMU-convention BVH (``deepmimic_<clip>.bvh``, walking and running repeated to
about 10 s) in ``humv_usd.assets.mocap_dir()`` (``$HUMV_USD_DATA/mocap`` or
``~/.cache/humv-usd/mocap``), outside git, with PROVENANCE.md recording source, hash and
licence. A scenario uses one with ``bvh = "<that folder>/deepmimic_walk.bvh"``.
Idempotent: a stamp holding the sdist hash and the converter's version makes a second run
return at once.
"""

from __future__ import annotations

import shutil
import sys
import tarfile
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from pinned_fetch import FetchError, download_pinned, is_current, staged  # noqa: E402

from humv_usd.assets import PYBULLET_SDIST_SHA256, PYBULLET_VERSION, mocap_dir  # noqa: E402

#: the clips converted (= humv_usd.human.deepmimic.CLIPS; imported after the stamp check, so a
#: second set-up run does not pay for numpy/scipy)
CLIPS = ("walk", "run", "jump", "crawl", "getup_faceup", "getup_facedown")

ROOT = f"pybullet-{PYBULLET_VERSION}/"
DATA = ROOT + "examples/pybullet/gym/pybullet_data/"
#: cycles of the wrapping clips (about 10 s of walking and running)
CYCLES = {"walk": 8, "run": 12, "crawl": 3}
CONVERTER = "2"
PROVENANCE = """# DeepMimic humanoid clips (fetched by tools/fetch_mocap.py)

- Source: pybullet {version} source distribution from PyPI, sha256 {sha}
  (`examples/pybullet/gym/pybullet_data/data/motions/humanoid3d_*.txt`, humanoid
  `.../humanoid/humanoid.urdf`); clips of Peng et al. (2018) "DeepMimic", ACM TOG 37(4):143.
- Licence: pybullet's LICENSE.txt (copied here): zlib for the repository's files except 'Extras'
  and examples/ThirdPartyLibs; the motions folder has no licence file of its own. DeepMimic's
  code is MIT (c) 2018 Xue Bin Peng. Upstream the clips come from public motion-capture databases
  (CMU Graphics Lab: free for all uses, no resale of the data even in converted form; SFU); the
  per-clip source is not recorded by the DeepMimic author (xbpeng/DeepMimic issue #176).
- Converted here to CMU-convention BVH (humv_usd.human.deepmimic, converter {conv}); not part of
  HumV-USD's repository; not to be resold.
- Files: {files}
"""


def main() -> int:
    dest = mocap_dir()
    want = f"{PYBULLET_SDIST_SHA256} {CONVERTER}"
    if is_current(dest, want):
        return 0
    from humv_usd.human import deepmimic
    from humv_usd.human.bvh import write_bvh

    assert deepmimic.CLIPS == CLIPS
    print(f"set-up: fetching DeepMimic motion clips (pybullet {PYBULLET_VERSION} sdist) into {dest}")
    wanted = {
        ROOT + "LICENSE.txt": "pybullet-LICENSE.txt",
        DATA + "humanoid/humanoid.urdf": "humanoid.urdf",
    }
    wanted |= {DATA + f"data/motions/humanoid3d_{c}.txt": f"humanoid3d_{c}.txt" for c in CLIPS}
    with tempfile.TemporaryDirectory() as tmp:
        try:
            sdist = download_pinned(
                "pybullet", PYBULLET_VERSION, PYBULLET_SDIST_SHA256, Path(tmp), sdist=True
            )
            with staged(dest, want, ".mocap-") as staging:
                with tarfile.open(sdist) as tf:
                    for member in tf.getmembers():
                        if member.name in wanted and member.isfile():
                            with (
                                tf.extractfile(member) as src,
                                open(staging / wanted[member.name], "wb") as out,
                            ):
                                shutil.copyfileobj(src, out)
                missing = [v for v in wanted.values() if not (staging / v).is_file()]
                if missing:
                    raise FetchError(f"pybullet sdist lacks {missing}")
                files = []
                for clip in CLIPS:
                    src = staging / f"humanoid3d_{clip}.txt"
                    frames, wraps = deepmimic.parse_clip(src.read_text(), str(src))
                    bvh = deepmimic.clip_to_bvh(frames, wraps, CYCLES.get(clip, 1) if wraps else 1, str(src))
                    write_bvh(staging / f"deepmimic_{clip}.bvh", bvh)
                    files.append(f"deepmimic_{clip}.bvh ({bvh.frame_count} frames at {bvh.fps:.0f} fps)")
                (staging / "PROVENANCE.md").write_text(
                    PROVENANCE.format(
                        version=PYBULLET_VERSION,
                        sha=PYBULLET_SDIST_SHA256,
                        conv=CONVERTER,
                        files=", ".join(files),
                    )
                )
        except FetchError as exc:
            print(f"set-up: {exc}", file=sys.stderr)
            return 1
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
