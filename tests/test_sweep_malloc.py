"""A sweep worker's heap reuses large temporaries even when started the way a Dask nanny starts
it (``MALLOC_TRIM_THRESHOLD_=65536``, which turns glibc's dynamic mmap threshold off)."""

import os
import subprocess
import sys

import pytest

PROBE = """
import resource, sys
import numpy as np
from humv_usd.sweep.tasks import tune_malloc
tuned = tune_malloc() if sys.argv[1] == "tune" else False
for _ in range(3):  # warm up
    a = np.ones(2**20); del a
f0 = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
for _ in range(40):  # 8 MB, like a frame's temporaries
    a = np.ones(2**20); a += 1.0; del a
print(int(tuned), resource.getrusage(resource.RUSAGE_SELF).ru_minflt - f0)
"""


def _faults(mode: str) -> tuple[int, int]:
    env = dict(os.environ, MALLOC_TRIM_THRESHOLD_="65536")  # distributed.nanny.pre-spawn-environ
    out = subprocess.run(
        [sys.executable, "-c", PROBE, mode], env=env, capture_output=True, text=True, check=True
    )
    tuned, faults = out.stdout.split()
    return int(tuned), int(faults)


@pytest.mark.skipif(sys.platform != "linux", reason="glibc mallopt")
def test_tuned_worker_reuses_freed_temporaries_instead_of_faulting_new_pages():
    untuned_flag, untuned = _faults("plain")
    tuned_flag, tuned = _faults("tune")
    assert (untuned_flag, tuned_flag) == (0, 1)
    # Dask's setting: every 8 MB array is a new mmap whose pages fault again (measured 20,640
    # faults for the 40 arrays; fewer than 2,048 each where the kernel backs some with huge pages)
    assert untuned > 40 * 100
    # tuned: the freed block is reused from the heap
    assert tuned < untuned / 20
