"""lookout: nonlinear observers and observer-based output-feedback control.

lookout computes in float64 (ship models span 1e-4 to 1e10), so importing it
enables ``jax_enable_x64``. Use float32 only as an explicit opt-in.

Importing lookout before JAX has computed anything also raises XLA:CPU's
``xla_cpu_small_while_loop_byte_threshold`` from 1 KiB to
:data:`SMALL_LOOP_BYTES` (unless ``XLA_FLAGS`` already sets backend extra options).
XLA:CPU then compiles a loop whose body touches less than that many bytes per
iteration into one function instead of dispatching each of its kernels in turn: a
single simulation of a few dozen states runs about 3.5x faster (docs/benchmarks.md).
It changes how loops are compiled, not what they compute.
"""

import os as _os
from importlib.metadata import PackageNotFoundError as _PackageNotFoundError
from importlib.metadata import version as _metadata_version

#: Per-iteration byte threshold below which XLA:CPU compiles a while loop as one
#: function (set at import, see the module docstring).
SMALL_LOOP_BYTES = 1_000_000


def _add_xla_flag(name: str, value: str) -> None:
    """Append ``--name=value`` to ``XLA_FLAGS`` unless the user already set ``name``."""
    flags = _os.environ.get("XLA_FLAGS", "")
    if name in flags:
        return
    _os.environ["XLA_FLAGS"] = f"{flags} --{name}={value}".strip()


_add_xla_flag("xla_backend_extra_options", f"xla_cpu_small_while_loop_byte_threshold={SMALL_LOOP_BYTES}")

import jax as _jax  # noqa: E402

_jax.config.update("jax_enable_x64", True)


def use_all_cpu_cores(count: int | None = None) -> None:
    """Expose each CPU core as a JAX device, so batches run on all cores.

    XLA runs a simulation loop on one thread per device; with one host device per
    core, :func:`lookout.simulate_batch` splits the runs across cores (about 2x on
    a 2-core machine). It sets ``XLA_FLAGS`` and so must be called before JAX first
    computes anything; if the user already set the device count, it does nothing.

    Parameters
    ----------
    count : int, optional
        Number of host devices; default ``os.cpu_count()``.
    """
    _add_xla_flag("xla_force_host_platform_device_count", str(count or _os.cpu_count() or 1))

from ._math import rotation as rotation  # noqa: E402
from ._math import ssa as ssa  # noqa: E402
from .controllers import SinusoidalThrust as SinusoidalThrust  # noqa: E402
from .environment import GaussMarkovBias as GaussMarkovBias  # noqa: E402
from .environment import LinearWaveModel as LinearWaveModel  # noqa: E402
from .models import DPVessel as DPVessel  # noqa: E402
from .models import VesselPlant as VesselPlant  # noqa: E402
from .models import VesselState as VesselState  # noqa: E402
from .models import northern_clipper as northern_clipper  # noqa: E402
from .observers import PassiveObserver as PassiveObserver  # noqa: E402
from .observers import injection_gains_from_normalized as injection_gains_from_normalized  # noqa: E402
from .observers import notch_filter_gains as notch_filter_gains  # noqa: E402
from .results import Trajectory as Trajectory  # noqa: E402
from .sensors import PositionHeadingSensor as PositionHeadingSensor  # noqa: E402
from .sim import Scenario as Scenario  # noqa: E402
from .sim import simulate as simulate  # noqa: E402
from .sim import seed_keys as seed_keys  # noqa: E402
from .sim import simulate_batch as simulate_batch  # noqa: E402

try:
    __version__ = _metadata_version("lookout")
except _PackageNotFoundError:  # pragma: no cover - running from a source tree that is not installed
    __version__ = "0+unknown"
