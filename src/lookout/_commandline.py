"""What the command's subcommands share: the console, checks of output paths, the
memory check before simulating, and the progress bar (used by :mod:`lookout.cli` and
:mod:`lookout.studies.cli`, which do not import each other's helpers).

Each check raises :class:`~lookout._validation.InputError` with one line that names the
option and the condition; the CLI prints it and exits with code 2.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from pathlib import Path

from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

from lookout._resources import PEAK_MEMORY_PER_RECORD_BYTE, available_memory, format_bytes, nearest_existing
from lookout._validation import InputError

console = Console(soft_wrap=True)
#: The width tables may take when the output is not a terminal (lookout.cli.main).
PIPE_WIDTH = 1000


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
    stderr = Console(stderr=True)
    return Progress(*columns, console=stderr, transient=True, disable=not stderr.is_terminal)


@contextlib.contextmanager
def simulating():
    """A progress bar on stderr while simulating; yields the engine's ``progress(done, total)``."""
    with progress_bar(TextColumn("simulating"), BarColumn(), TextColumn("{task.percentage:>5.1f}%"), TimeRemainingColumn()) as bar:
        task = bar.add_task("run", total=1.0)
        yield lambda done, total: bar.update(task, completed=done / total)


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


def check_memory(batches, runs_option: str = "--runs", duration_option: str = "--duration", runs: int | None = None, where: str | None = None) -> None:
    """Refuse a study whose records and working memory would not fit, before simulating.

    ``batches`` are (scenario, runs) simulated one after another, so the largest
    one sets the peak; ``runs`` is what the user asked for (a reproduction may batch
    more, e.g. both of Kim's observers); ``where`` (a file) starts the message. Nothing
    that grows with the runs exists yet when this runs.
    """
    from lookout.sim import record_nbytes, working_nbytes
    from lookout.sim.engine import RECORD_OVERHEAD_BYTES

    def need_of(pair):
        scenario, count = pair
        return scenario.n_records * (PEAK_MEMORY_PER_RECORD_BYTE * count * record_nbytes(scenario) + RECORD_OVERHEAD_BYTES) + count * working_nbytes(scenario)

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
            f"and {format_bytes(available)} are available: " + (f"use fewer {runs_option} or a shorter {duration_option}" if runs > 1 else f"use a shorter {duration_option}")
        )


