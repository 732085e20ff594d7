"""What the command's subcommands share: the console, checks of output paths, the
memory check before simulating, the progress bar (used by :mod:`lookout.cli` and
:mod:`lookout.studies.cli`, which do not import each other's helpers), and the
command's compilation cache.

Each check raises :class:`~lookout._validation.InputError` with one line that names the
option and the condition; the CLI prints it and exits with code 2.

This module imports neither NumPy nor JAX (nor ``rich.progress``) at its top: the
command imports it before answering ``--version`` and ``--help``.
"""

from __future__ import annotations

import contextlib
import os
import sys
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING

from rich.console import Console

from lookout._resources import PEAK_MEMORY_PER_RECORD_BYTE, available_memory, format_bytes, nearest_existing
from lookout._validation import InputError

if TYPE_CHECKING:
    from rich.progress import Progress

console = Console(soft_wrap=True)
#: The width tables may take when the output is not a terminal (lookout.cli.main).
PIPE_WIDTH = 1000

#: The environment variable that switches the command's compilation cache off (``0``).
COMPILATION_CACHE_SWITCH = "LOOKOUT_COMPILATION_CACHE"
#: The compilation cache keeps at most this many bytes: each command starts by removing
#: the least recently used programs beyond it. (JAX's own bound,
#: ``jax_compilation_cache_max_size``, needs the filelock package, which lookout does
#: not depend on.)
COMPILATION_CACHE_MAX_BYTES = 1_000_000_000
#: Programs that compile faster than this (s) are not cached. JAX's default is 1 s; the
#: command keeps every program, since on the CPU it compiles dozens of small ones that add
#: up, and they take a few kB each (docs/benchmarks.md, "Time to first result").
COMPILATION_CACHE_MIN_COMPILE_SECONDS = 0.0


#: The exit code of ``lookout run``, ``replay`` and ``live`` when a run
#: failed (status ``diverged``: a non-finite estimate or truth, or an error beyond the
#: divergence limit); 1 is a condition that fails (``lookout design``) or a failed write,
#: 2 bad input.
DIVERGED_EXIT_CODE = 3


def writable_folder(option: str, folder: Path, what: str) -> None:
    """Fail unless ``folder`` can be written into: it exists and is writable, or its
    nearest existing ancestor is a writable folder (every output's missing parent
    folders are created when it is written: one rule for every ``--out``).

    Permission bits do not answer that (root passes them, /proc and read-only file
    systems refuse anyway), so a nameless temporary file is created and removed.
    """
    existing = nearest_existing(folder)
    if not existing.is_dir():
        raise InputError(f"{option}: {existing} is a file, not a folder (on the way to {what})")
    folder = existing if existing != folder.absolute() else folder
    if not os.access(folder, os.W_OK | os.X_OK):
        raise InputError(f"{option}: the folder {folder} is not writable")
    try:
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError as error:
        raise InputError(f"{option}: cannot write into the folder {folder}: {error.strerror}") from None


def output_folder(option: str, text: str) -> Path:
    """Check an output folder before any work: not empty, not a file, and it or its
    nearest existing ancestor writable."""
    if not text.strip():
        raise InputError(f"{option} must name a folder; got an empty path")
    folder = Path(text)
    if folder.exists():
        if not folder.is_dir():
            raise InputError(f"{option} must be a folder; {folder} is an existing file")
        writable_folder(option, folder, "the results")
    else:
        writable_folder(option, folder.absolute().parent, f"{option} {text}")
    return folder


def created_folder(option: str, text: str) -> Path:
    """:func:`output_folder`, created with its missing parents."""
    folder = output_folder(option, text)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise InputError(f"{option}: cannot create {folder}: {error.strerror}") from None
    return folder


def progress_bar(*columns) -> Progress:
    """A transient progress bar on stderr, shown only where someone watches (a terminal):
    a log or a pipe gets none."""
    from rich.progress import Progress

    stderr = Console(stderr=True)
    return Progress(*columns, console=stderr, transient=True, disable=not stderr.is_terminal)


#: A simulation whose time left is estimated above this (s) says so in one line on stderr,
#: terminal or not, so that a long run is never silent.
LONG_RUN_SECONDS = 30.0


@contextlib.contextmanager
def simulating() -> Iterator[Callable[[float, float], None]]:
    """A progress bar on stderr while simulating; yields the engine's ``progress(done, total)``.

    After the second segment (the first one compiles), a run whose time left is
    estimated above :data:`LONG_RUN_SECONDS` says so in one line (:func:`time_left`)."""
    import time

    from rich.progress import BarColumn, TextColumn, TimeRemainingColumn

    start = time.perf_counter()
    seen: list[tuple[float, float]] = []

    with progress_bar(TextColumn("simulating"), BarColumn(), TextColumn("{task.percentage:>5.1f}%"), TimeRemainingColumn()) as bar:
        task = bar.add_task("run", total=1.0)

        def progress(done, total) -> None:
            bar.update(task, completed=done / total)
            seen.append((time.perf_counter(), done))
            if len(seen) == 2:
                line = time_left(seen, total, start)
                if line is not None:
                    print(line, file=sys.stderr, flush=True)

        yield progress


def time_left(seen: list[tuple[float, float]], total: float, start: float) -> str | None:
    """The line a long simulation prints: its time left from the pace between the first
    two segments ``seen`` (clock, records done), or None when under :data:`LONG_RUN_SECONDS`."""
    (first, done_first), (second, done_second) = seen[:2]
    if done_second <= done_first or done_second >= total:
        return None
    left = (second - first) / (done_second - done_first) * (total - done_second)
    if left <= LONG_RUN_SECONDS:
        return None
    return (
        f"simulating: about {_clock(left)} left ({done_second / total:.0%} of the records in {_clock(second - start)}, "
        f"compilation included; the pace is that of the last {done_second - done_first:g} records)"
    )


def _clock(seconds: float) -> str:
    """``45 s``, ``4 min 10 s``, ``2 h 05 min``."""
    seconds = int(round(seconds))
    if seconds < 60:
        return f"{seconds} s"
    if seconds < 3600:
        return f"{seconds // 60} min {seconds % 60:02d} s"
    return f"{seconds // 3600} h {seconds % 3600 // 60:02d} min"


def image_file(option: str, text: str) -> Path:
    """Check a figure's file name: a suffix matplotlib writes, in an existing writable folder."""
    from matplotlib.figure import Figure

    if not text.strip():
        raise InputError(f"{option} must name a file; got an empty path")
    path = Path(text)
    if path.is_dir():
        raise InputError(f"{option} must name a file, not the folder {path}; e.g. {path / 'bode.png'}")
    formats = Figure().canvas.get_supported_filetypes()
    suffix = path.suffix.lower().lstrip(".")
    if suffix not in formats:
        listed = ["png", "pdf", "svg", *sorted(set(formats) - {"png", "pdf", "svg"})]
        raise InputError(f"{option} must end in a format matplotlib writes ({', '.join('.' + name for name in listed)}); got {text}")
    writable_folder(option, path.absolute().parent, text)
    return path


def check_memory(
    batches, runs_option: str = "--runs", duration_option: str = "--duration", runs: int | None = None, where: str | None = None
) -> None:
    """Refuse a study whose records and working memory would not fit, before simulating.

    ``batches`` are (scenario, runs) simulated one after another, so the largest
    one sets the peak; ``runs`` is what the user asked for (a reproduction may batch
    more, e.g. both of Kim's observers); ``where`` (a file) starts the message. Nothing
    that grows with the runs exists yet when this runs.
    """
    from lookout.sim import record_nbytes, working_nbytes
    from lookout.sim.memory import RECORD_OVERHEAD_BYTES

    def need_of(pair):
        scenario, count = pair
        return scenario.n_records * (PEAK_MEMORY_PER_RECORD_BYTE * count * record_nbytes(scenario) + RECORD_OVERHEAD_BYTES) + count * working_nbytes(
            scenario
        )

    scenario, batch = max(batches, key=need_of)
    need = need_of((scenario, batch))
    runs = batch if runs is None else runs
    available = available_memory()
    if available is not None and need > available:
        largest = "" if batch == runs else "its largest batch: "
        working = working_nbytes(scenario)
        steps = f" + {batch} x {format_bytes(working)} while a sample is taken" if working > 2**20 else ""
        raise InputError(
            f"{where + ': ' if where else ''}{runs_option} {runs} over {duration_option} {scenario.duration:g} would need about {format_bytes(need)} of memory "
            f"({largest}{batch} run(s) x {scenario.n_records} records x {record_nbytes(scenario)} B, x{PEAK_MEMORY_PER_RECORD_BYTE} while writing results{steps}), "
            f"and {format_bytes(available)} are available: "
            + (f"use fewer {runs_option} or a shorter {duration_option}" if runs > 1 else f"use a shorter {duration_option}")
        )


def compilation_cache_folder() -> Path | None:
    """Where the command keeps the programs it compiled: ``$XDG_CACHE_HOME/lookout/jax``,
    or ``~/.cache/lookout/jax`` (the XDG base directory rule: a relative
    ``XDG_CACHE_HOME`` is ignored). None when ``LOOKOUT_COMPILATION_CACHE=0`` switches
    the cache off, or when there is no home folder."""
    switch = os.environ.get(COMPILATION_CACHE_SWITCH, "1").strip().lower()
    if switch not in ("0", "1", "off", "on", "false", "true", "no", "yes", ""):
        raise InputError(f"{COMPILATION_CACHE_SWITCH} must be 0 (the compilation cache off) or 1 (on); got {switch[:40]!r}")
    if switch in ("0", "off", "false", "no"):
        return None
    base = os.environ.get("XDG_CACHE_HOME", "")
    if not os.path.isabs(base):
        try:
            base = os.path.join(Path.home(), ".cache")
        except RuntimeError:  # no home folder to be found
            return None
    return Path(base) / "lookout" / "jax"


def use_compilation_cache() -> Path | None:
    """Let JAX keep the programs the command compiles, so that running the same file
    again loads them instead of compiling them (JAX's persistent compilation cache).

    The folder is :func:`compilation_cache_folder`'s; returns it, or None when the cache
    is off, when its folder cannot be written (the command then compiles as without
    it), or when JAX is given a cache folder already (``JAX_COMPILATION_CACHE_DIR``, as
    the tests do): JAX's own setting wins. Only what took
    :data:`COMPILATION_CACHE_MIN_COMPILE_SECONDS` or more to compile is kept, and the
    folder is first trimmed to :data:`COMPILATION_CACHE_MAX_BYTES`. JAX is not imported
    here: before JAX is imported, the settings go through JAX's environment variables
    (which the command's worker processes inherit).
    """
    folder = compilation_cache_folder()
    jax = sys.modules.get("jax")
    if folder is None or "JAX_COMPILATION_CACHE_DIR" in os.environ or (jax is not None and jax.config.jax_compilation_cache_dir is not None):
        return None
    existing = nearest_existing(folder)
    if not (existing.is_dir() and os.access(existing, os.R_OK | os.W_OK | os.X_OK)):
        print(
            f"note: the compilation cache folder {folder} cannot be read and written ({existing} is not a folder this user may "
            f"read and write): compiling without it; {COMPILATION_CACHE_SWITCH}=0 leaves the cache out",
            file=sys.stderr,
        )
        return None
    trim_folder(folder, COMPILATION_CACHE_MAX_BYTES)
    settings = {"jax_compilation_cache_dir": str(folder), "jax_persistent_cache_min_compile_time_secs": COMPILATION_CACHE_MIN_COMPILE_SECONDS}
    for name, value in settings.items():
        if jax is None:
            os.environ.setdefault(name.upper(), str(value))
        else:
            jax.config.update(name, value)
    return folder


def trim_folder(folder: Path, max_bytes: int) -> None:
    """Remove the least recently used files of ``folder`` (its own, not those of its
    subfolders) until they hold at most ``max_bytes``. Use is the later of a file's
    access and modification times (where the file system records no access, the oldest
    go first). A file another process removed meanwhile is passed over."""
    entries = []
    try:
        with os.scandir(folder) as scan:
            for entry in scan:
                with contextlib.suppress(OSError):
                    if entry.is_file(follow_symlinks=False):
                        stat = entry.stat(follow_symlinks=False)
                        entries.append((max(stat.st_atime, stat.st_mtime), stat.st_size, entry.path))
    except OSError:  # no folder yet
        return
    total = sum(size for _, size, _ in entries)
    for _, size, path in sorted(entries):
        if total <= max_bytes:
            break
        with contextlib.suppress(OSError):
            os.unlink(path)
        total -= size
