"""Keep freed heap memory in the process instead of handing it back to the operating system.

The planner allocates and frees numpy temporaries of a few hundred KB many times per cycle (the rollouts'
[rollouts, samples, vehicles] arrays). glibc serves blocks above its mmap threshold (128 KB) with fresh pages and
returns them on free, so every such temporary costs page faults and zeroing: ~1,300 minor faults and ~10 % of a
20-agent behaviour cycle (bench/planner.py). Raising the mmap and trim thresholds keeps those blocks on the heap
for reuse. Other C libraries: nothing to do.
"""
from __future__ import annotations

import ctypes
import ctypes.util
import functools

_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3  # glibc's mallopt parameter numbers
MMAP_THRESHOLD = 32 << 20  # [bytes] blocks up to this size come from the heap (glibc's largest allowed value)
TRIM_THRESHOLD = 256 << 20  # [bytes] free memory kept at the top of the heap


@functools.cache
def keep_freed_memory() -> bool:
    """Set glibc's thresholds once per process; whether they were set (False where malloc is not glibc's)."""
    name = ctypes.util.find_library("c")
    libc = ctypes.CDLL(name) if name else None
    mallopt = getattr(libc, "mallopt", None)
    if mallopt is None or not hasattr(libc, "gnu_get_libc_version"):
        return False
    return bool(mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD)) and bool(mallopt(_M_TRIM_THRESHOLD, TRIM_THRESHOLD))
