"""lookout: nonlinear observers and observer-based output-feedback control.

Importing lookout does one thing to the process: it enables JAX's float64
(``jax_enable_x64``), because ship models span 1e-4 to 1e10 (M33 of a supply vessel
is 3.7e9) and float32 loses the small terms. Use float32 only as an explicit opt-in.
It sets no environment variable.

:func:`configure_cpu`, called before JAX computes anything (the ``lookout`` command,
the benchmarks and the tests do), sets two XLA:CPU options through ``XLA_FLAGS``:

- ``xla_cpu_small_while_loop_byte_threshold`` raised from 1 KiB to
  :data:`SMALL_LOOP_BYTES`: XLA:CPU then compiles a loop whose body touches less
  than that many bytes per iteration into one function instead of dispatching each
  of its kernels in turn; a single simulation runs about 3.5x faster
  (docs/benchmarks.md). It changes how loops are compiled, not what they compute.
- one host device per CPU core, so that :func:`simulate_batch` splits its runs
  across cores (about 2x on 2 cores).

XLA reads these options once, when its CPU backend starts, and for the whole
process; that is why they are an explicit call and not a side effect of importing.
"""

import os as _os
from importlib.metadata import PackageNotFoundError as _PackageNotFoundError
from importlib.metadata import version as _metadata_version

import jax as _jax

_jax.config.update("jax_enable_x64", True)

#: Per-iteration byte threshold below which XLA:CPU compiles a while loop as one
#: function (set by :func:`configure_cpu`).
SMALL_LOOP_BYTES = 1_000_000


def _add_xla_flag(name: str, value: str) -> None:
    """Append ``--name=value`` to ``XLA_FLAGS`` unless the user already set ``name``."""
    flags = _os.environ.get("XLA_FLAGS", "")
    if name in flags:
        return
    _os.environ["XLA_FLAGS"] = f"{flags} --{name}={value}".strip()


def configure_cpu(devices: int | None = None) -> None:
    """Set lookout's XLA:CPU options: the small-loop threshold and one device per core.

    Call it before JAX first computes anything (XLA reads ``XLA_FLAGS`` once, when
    its CPU backend starts); options the user already set in ``XLA_FLAGS`` are left
    alone. See the module docstring for what each option does.

    Parameters
    ----------
    devices : int, optional
        Number of host devices; default ``os.cpu_count()``.
    """
    _add_xla_flag("xla_backend_extra_options", f"xla_cpu_small_while_loop_byte_threshold={SMALL_LOOP_BYTES}")
    _add_xla_flag("xla_force_host_platform_device_count", str(devices or _os.cpu_count() or 1))


from ._math import rotation as rotation  # noqa: E402
from ._math import ssa as ssa  # noqa: E402
from .actuators import IdealActuator as IdealActuator  # noqa: E402
from .components import Actuator as Actuator  # noqa: E402
from .components import ContinuousObserver as ContinuousObserver  # noqa: E402
from .components import Controller as Controller  # noqa: E402
from .components import Layout as Layout  # noqa: E402
from .components import Observer as Observer  # noqa: E402
from .components import Plant as Plant  # noqa: E402
from .components import Reference as Reference  # noqa: E402
from .components import Sensor as Sensor  # noqa: E402
from .components import Signal as Signal  # noqa: E402
from .controllers import NoControl as NoControl  # noqa: E402
from .controllers import SinusoidalInput as SinusoidalInput  # noqa: E402
from .environment import GaussMarkovBias as GaussMarkovBias  # noqa: E402
from .environment import LinearWaveModel as LinearWaveModel  # noqa: E402
from .models import CartPendulum as CartPendulum  # noqa: E402
from .models import DPVessel as DPVessel  # noqa: E402
from .models import FreePendulum as FreePendulum  # noqa: E402
from .models import FurutaPendulum as FurutaPendulum  # noqa: E402
from .models import ManipulatorPlant as ManipulatorPlant  # noqa: E402
from .models import TwoLinkArm as TwoLinkArm  # noqa: E402
from .models import VesselPlant as VesselPlant  # noqa: E402
from .models import VesselState as VesselState  # noqa: E402
from .models import northern_clipper as northern_clipper  # noqa: E402
from .observers import PassiveObserver as PassiveObserver  # noqa: E402
from .observers import VelocityObserver as VelocityObserver  # noqa: E402
from .observers import injection_gains_from_normalized as injection_gains_from_normalized  # noqa: E402
from .observers import notch_filter_gains as notch_filter_gains  # noqa: E402
from .reference import NoReference as NoReference  # noqa: E402
from .results import Trajectory as Trajectory  # noqa: E402
from .results import write_netcdf as write_netcdf  # noqa: E402
from .sensors import JointEncoder as JointEncoder  # noqa: E402
from .sensors import PositionHeadingSensor as PositionHeadingSensor  # noqa: E402
from .sim import Scenario as Scenario  # noqa: E402
from .sim import Stepper as Stepper  # noqa: E402
from .sim import filter as filter  # noqa: E402, A004
from .sim import seed_keys as seed_keys  # noqa: E402
from .sim import simulate as simulate  # noqa: E402
from .sim import simulate_batch as simulate_batch  # noqa: E402

try:
    __version__ = _metadata_version("lookout")
except _PackageNotFoundError:  # pragma: no cover - running from a source tree that is not installed
    __version__ = "0+unknown"
