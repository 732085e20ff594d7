"""Memory and disk before work: what is available, and one-line refusals with the numbers.

Every path that sizes work from user input (runs, seeds, sweep points, duration)
estimates what it will hold and compares it with what the machine has *before* it
allocates anything, so that a study too big for the machine is refused with one line
instead of being killed by the kernel.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

#: The peak memory of a study is about this many times its records: the simulated
#: segments and their concatenation, the xarray copy, NetCDF and metric buffers.
#: Measured 3.6x (40 runs x 3000 s of fossen-strand-1999: 346 MB of records, 1.23 GB
#: of resident memory above the 0.57 GB of a single run).
PEAK_MEMORY_PER_RECORD_BYTE = 4


def format_bytes(count: float) -> str:
    """``1.23 GB``: decimal units, three significant digits."""
    for unit, size in (("EB", 1e18), ("PB", 1e15), ("TB", 1e12), ("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if count >= size:
            return f"{count / size:.3g} {unit}"
    return f"{count:.0f} B"


def available_memory() -> int | None:
    """Bytes of memory available to a new allocation (Linux MemAvailable), or None if unknown."""
    try:
        with open("/proc/meminfo") as meminfo:
            for line in meminfo:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


def nearest_existing(path: str | Path) -> Path:
    """``path`` made absolute, or its nearest ancestor that exists (where an output whose
    missing parents will be created lands)."""
    path = Path(path).absolute()
    while not path.exists() and path != path.parent:
        path = path.parent
    return path


def free_disk(path: str | Path) -> int | None:
    """Bytes free on the file system that holds ``path`` (or its nearest existing parent)."""
    try:
        return shutil.disk_usage(nearest_existing(path)).free
    except OSError:
        return None


def refuse_unless_it_fits(need: float, what: str, hint: str, *, available: float | None = None, resource: str = "memory") -> None:
    """Raise ``ValueError`` ("``what`` would need about N of memory (...), and M are
    available: ``hint``") when ``need`` exceeds ``available`` (default: the memory
    available now). Nothing is refused when the amount available is unknown."""
    if available is None:
        available = available_memory() if resource == "memory" else None
    if available is not None and need > available:
        raise ValueError(f"{what} would need about {format_bytes(need)} of {resource}, and {format_bytes(available)} are available: {hint}")
