"""lookout: nonlinear observers and observer-based output-feedback control.

Importing lookout does one thing to the process: it enables JAX's float64
(``jax_enable_x64``), because ship models span 1e-4 to 1e10 (M33 of a supply vessel
is 3.7e9) and float32 loses the small terms. Use float32 only as an explicit opt-in.
It sets no environment variable. Importing lookout does not import JAX (so that
``lookout --version`` and ``--help`` answer at once): when JAX is imported already,
float64 is enabled there and then; otherwise as soon as JAX's own import finishes,
whoever imports it, and so before anything computes.

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
import sys as _sys


def _enable_float64(jax) -> None:
    jax.config.update("jax_enable_x64", True)


class _Float64OnImport:
    """Finds the ``jax`` package as the other finders do, with a loader that enables
    float64 as soon as JAX's import has run; the finder then leaves ``sys.meta_path``."""

    def find_spec(self, name, path, target=None):
        if name != "jax":
            return None
        for finder in _sys.meta_path:
            spec = None if finder is self else getattr(finder, "find_spec", lambda *_: None)(name, path, target)
            if spec is not None:
                if spec.loader is not None:
                    spec.loader = _EnablingLoader(spec.loader, self)
                return spec
        return None


class _EnablingLoader:
    """``loader``, which enables float64 once it has executed the module."""

    def __init__(self, loader, finder: _Float64OnImport):
        self._loader = loader
        self._finder = finder

    def create_module(self, spec):
        return self._loader.create_module(spec)

    def exec_module(self, module):
        self._loader.exec_module(module)
        _enable_float64(module)
        if self._finder in _sys.meta_path:
            _sys.meta_path.remove(self._finder)

    def __getattr__(self, name):  # get_resource_reader, is_package, ...: the original loader's
        return getattr(self._loader, name)


if "jax" in _sys.modules:
    _enable_float64(_sys.modules["jax"])
elif not any(type(finder).__qualname__ == "_Float64OnImport" for finder in _sys.meta_path):  # one, even if lookout is reloaded
    _sys.meta_path.insert(0, _Float64OnImport())

#: Per-iteration byte threshold below which XLA:CPU compiles a while loop as one
#: function (set by :func:`configure_cpu`).
SMALL_LOOP_BYTES = 1_000_000


def _add_xla_flag(name: str, value: str) -> bool:
    """Append ``--name=value`` to ``XLA_FLAGS`` unless the user already set ``name``;
    True when it was added."""
    flags = _os.environ.get("XLA_FLAGS", "")
    if name in flags:
        return False
    _os.environ["XLA_FLAGS"] = f"{flags} --{name}={value}".strip()
    return True


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
    added = _add_xla_flag("xla_backend_extra_options", f"xla_cpu_small_while_loop_byte_threshold={SMALL_LOOP_BYTES}")
    added = _add_xla_flag("xla_force_host_platform_device_count", str(devices or _os.cpu_count() or 1)) or added
    if added and _backend_started():
        import warnings

        warnings.warn(
            "lookout.configure_cpu: JAX's backend has already started, so XLA will not read these options in this process; "
            "call configure_cpu before anything computes with JAX (or set XLA_FLAGS before starting Python)",
            RuntimeWarning,
            stacklevel=2,
        )


def _backend_started() -> bool:
    """Whether JAX has started a backend (then XLA_FLAGS is read already). JAX has no
    public call for this; when its private one is missing, say no."""
    if "jax" not in _sys.modules:
        return False
    try:
        from jax._src import xla_bridge

        return bool(xla_bridge.backends_are_initialized())
    except Exception:  # pragma: no cover - a JAX without the private call
        return False


#: The public API, name -> the module that defines it. A name is imported when it is
#: first used (PEP 562), so ``import lookout`` imports neither JAX nor the models,
#: observers and xarray, and ``lookout --version`` answers at once.
_PUBLIC = {
    "rotation": "._math",
    "ssa": "._math",
    "IdealActuator": ".null_components",
    "SaturatingActuator": ".actuators",
    "ThrusterLayout": ".actuators",
    "ThrusterSystem": ".actuators",
    "Actuator": ".components",
    "ContinuousObserver": ".components",
    "Controller": ".components",
    "Layout": ".components",
    "Observer": ".components",
    "Plant": ".components",
    "Reference": ".components",
    "Sensor": ".components",
    "Signal": ".components",
    "NoControl": ".controllers",
    "SinusoidalInput": ".controllers",
    "GaussMarkovBias": ".environment",
    "LinearWaveModel": ".environment",
    "CartPendulum": ".models",
    "DPVessel": ".models",
    "FreePendulum": ".models",
    "FurutaPendulum": ".models",
    "ManipulatorPlant": ".models",
    "TwoLinkArm": ".models",
    "VesselPlant": ".models",
    "VesselState": ".models",
    "northern_clipper": ".models",
    "PassiveObserver": ".observers",
    "VelocityObserver": ".observers",
    "injection_gains_from_normalized": ".observers",
    "notch_filter_gains": ".observers",
    "smooth": ".observers",
    "NoReference": ".null_components",
    "Trajectory": ".results",
    "write_netcdf": ".results",
    "JointEncoder": ".sensors",
    "PositionHeadingSensor": ".sensors",
    "Scenario": ".sim",
    "Stepper": ".sim",
    "filter": ".sim",
    "seed_keys": ".sim",
    "simulate": ".sim",
    "simulate_batch": ".sim",
    "stack_scenarios": ".sim",
}
__all__ = ["SMALL_LOOP_BYTES", "configure_cpu", "__version__", *_PUBLIC]


def __getattr__(name: str):
    if name == "__version__":
        value = _installed_version()
    elif name in _PUBLIC:
        import importlib

        value = getattr(importlib.import_module(_PUBLIC[name], __name__), name)
    else:
        raise AttributeError(f"module 'lookout' has no attribute {name!r}")
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(__all__))


def _installed_version() -> str:
    """The installed distribution's version (importlib.metadata is read on first use)."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("lookout")
    except PackageNotFoundError:  # pragma: no cover - running from a source tree that is not installed
        return "0+unknown"
