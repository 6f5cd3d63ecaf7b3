"""How a one-shot command takes memory from the system.

glibc's ``malloc`` hands every large block (above 128 kB at first, the threshold rising up to 32 MB as blocks
are freed) straight from the kernel with ``mmap`` and gives it back on ``free``. A command that animates a long
recording makes many such arrays in turn (10 minutes of 16 kHz audio in float64 is 77 MB; the fbank windows,
the motion windows and their candidates are of that size), so each is fresh memory whose every page the kernel
faults in and zeroes again. On a 2-core virtual machine, generating 10 minutes of speech took 330 000-350 000
page faults and 2.1-2.6 s of system time, against 140 000-155 000 and 1.4 s with the freed memory kept for the
arrays that follow; five such recordings in one process, 231 000 faults against 839 000, its peak memory
1.18 GB against 1.14 (``bench/results/cpu.md``, 2026-11-30). A one-shot command ends soon after its largest
array, so keeping that memory costs it little; long-running servers are left to glibc's defaults.
"""

from __future__ import annotations

import ctypes
import platform

# mallopt's parameters (glibc's malloc.h)
_M_TRIM_THRESHOLD, _M_TOP_PAD, _M_MMAP_MAX = -1, -2, -4
#: memory kept at the top of the heap after a free, and asked for beyond each request (bytes)
KEEP_BYTES = 2**31 - 1
TOP_PAD_BYTES = 64 << 20


def keep_freed_memory() -> bool:
    """On glibc, make ``malloc`` take every block from the heap (no ``mmap``) and keep what is freed for the
    blocks that follow, instead of returning it to the kernel; True where that was set. Elsewhere (another C
    library, another system) nothing changes and it returns False. For commands that run once and end, not for
    servers: the process holds its largest working set until it exits."""
    if platform.system() != "Linux" or platform.libc_ver()[0] != "glibc":
        return False
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes, mallopt.restype = [ctypes.c_int, ctypes.c_int], ctypes.c_int
    return all(mallopt(param, value) == 1 for param, value in
               ((_M_MMAP_MAX, 0), (_M_TRIM_THRESHOLD, KEEP_BYTES), (_M_TOP_PAD, TOP_PAD_BYTES)))
