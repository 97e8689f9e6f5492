"""A sweep worker's heap reuses large temporaries even when started the way a Dask nanny starts
it (``MALLOC_TRIM_THRESHOLD_=65536``, which turns glibc's dynamic mmap threshold off)."""

import os
import subprocess
import sys

import pytest

PROBE = """
import ctypes, resource, sys
# 4 KiB pages for this process (PR_SET_THP_DISABLE): with transparent huge pages "always", the
# kernel may back an 8 MB mmap with a few 2 MB pages, and the count below would measure the
# kernel's page size instead of whether the heap reuses the freed block (seen in CI: 200 faults)
ctypes.CDLL(None).prctl(41, 1, 0, 0, 0)
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


RELEASE_PROBE = """
import drjit as dr
from humv_usd import mode
mode.mitsuba()
def rss():
    return int(open("/proc/self/statm").read().split()[1]) * 4096 / 2**20
import numpy as np
x = np.random.default_rng(0).random(50_000_000, dtype=np.float32)
a = mode.mitsuba().Float(x)
b = dr.sqrt(a) + a  # 200 MB arrays on the host (LLVM)
dr.eval(b)
del a, b, x
before = rss()  # the freed arrays stay in Dr.Jit's cache
mode.release_memory()
print(before, rss())
"""


@pytest.mark.skipif(sys.platform != "linux", reason="/proc/self/statm")
def test_release_memory_hands_dr_jits_cached_arrays_back():
    out = subprocess.run([sys.executable, "-c", RELEASE_PROBE], capture_output=True, text=True, check=True)
    before, after = (float(x) for x in out.stdout.split()[-2:])
    assert before - after > 150.0, (before, after)


def test_kernel_cache_dropped_every_n_frames_across_render_calls(monkeypatch):
    from humv_usd import mode

    drops = []
    monkeypatch.setattr(mode, "release_kernel_cache", lambda: drops.append(1))
    monkeypatch.setattr(mode, "_frames_since_flush", [0])
    # a sweep worker: tasks of 4 frames, each its own render call; the interval is 10 frames
    flags = [mode.frame_rendered(10) for _task in range(5) for _frame in range(4)]
    assert len(drops) == 2 and [i for i, f in enumerate(flags) if f] == [9, 19]


def test_worker_releases_memory_only_after_growing_past_its_first_render_task(monkeypatch):
    from humv_usd import mode
    from humv_usd.sweep import tasks

    released = []
    monkeypatch.setattr(mode, "release_memory", lambda: released.append(1))
    monkeypatch.setattr(tasks, "_first_task_rss", [])
    rss = iter([2000.0, 2090.0, 2200.0, 700.0])
    monkeypatch.setattr(tasks, "_rss_mb", lambda: (next(rss), 0.0))
    # first task sets the mark; +4.5 % keeps; +10 % releases; then below again
    assert [tasks.release_memory_if_grown() for _ in range(4)] == [False, False, True, False]
    assert released == [1]


TASK_PEAK_PROBE = """
import numpy as np
from humv_usd.sweep import tasks
tasks.start_task_peak()
a = np.ones(40_000_000)  # 320 MB, touched
del a
big = tasks.task_peak_mb()
tasks.start_task_peak()  # the next task
b = np.ones(5_000_000)  # 40 MB
del b
small = tasks.task_peak_mb()
print(big, small, tasks._rss_mb()[1])
"""


@pytest.mark.skipif(sys.platform != "linux", reason="/proc/self/clear_refs")
def test_a_tasks_own_peak_is_measured_and_the_workers_peak_kept():
    """A worker's lifetime peak only says which task was the heaviest so far; each task records
    its own peak (the kernel's high-water mark reset at its start) and the worker's is kept."""
    out = subprocess.run([sys.executable, "-c", TASK_PEAK_PROBE], capture_output=True, text=True, check=True)
    big, small, process = (float(x) for x in out.stdout.split()[-3:])
    assert big - small > 250.0, (big, small)
    assert process >= big
