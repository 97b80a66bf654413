"""Memory given back to the system after a large message (a node that took ten
100,000-point references holds no more than one that took one).

Two things kept a controller that had taken a few 100,000-point references (9.6 MB each)
at 100-180 MB more than before, in steps that never came back (the fault soak's memory
criterion, docs/safety.md):

- glibc's allocator serves a block of at least ``M_MMAP_THRESHOLD`` bytes from the system
  and returns it on free, but raises that threshold, up to 32 MB, to the size of every such
  block freed. After the first large message, the megabyte arrays of a reference came from
  the heap, whose freed middle stays resident. :func:`large_blocks_from_the_system` sets the
  threshold (which also stops the raising): a node's per-tick arrays are far smaller, so
  only a large message's blocks take the system call.
- reading a message into Python objects (a reference's points: a peak of ~180 MB for 9.6 MB)
  leaves small freed blocks spread over many pages. :func:`give_back_free_memory`
  (``malloc_trim``) returns every whole free page: measured on six such references built in
  a process doing nothing else, 286 MB → 233 MB. It walks the heaps (a few milliseconds),
  so it is called after a large message, never per tick (and by the recorder every
  10 s, from its executor's thread: ``Recorder._give_back``).

Both are glibc's; on another C library they do nothing and say so (False).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import functools

#: Blocks of at least this many bytes come from the system and go back to it when freed.
LARGE_BLOCK_BYTES = 1 << 20
#: mallopt's parameter number for the threshold (glibc's malloc.h).
_M_MMAP_THRESHOLD = -3


@functools.cache
def _libc() -> ctypes.CDLL | None:
    name = ctypes.util.find_library("c")
    try:
        libc = ctypes.CDLL(name) if name else None
    except OSError:
        return None
    if libc is None or not all(hasattr(libc, f) for f in ("mallopt", "malloc_trim")):
        return None  # not glibc
    libc.mallopt.argtypes = (ctypes.c_int, ctypes.c_int)
    libc.malloc_trim.argtypes = (ctypes.c_size_t,)
    return libc


def large_blocks_from_the_system(threshold: int = LARGE_BLOCK_BYTES) -> bool:
    """Blocks of at least ``threshold`` bytes served by the system and returned on free,
    whatever was freed before; False where that cannot be set."""
    libc = _libc()
    return bool(libc is not None and libc.mallopt(_M_MMAP_THRESHOLD, threshold) == 1)


def give_back_free_memory() -> bool:
    """Return the allocator's free pages to the system; False where that is not possible."""
    libc = _libc()
    if libc is None:
        return False
    libc.malloc_trim(0)
    return True
