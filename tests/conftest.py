import os
import sys

# Tests compile far more than they run, so they ask XLA:CPU for programs that compile
# faster (every test passes either way; arithmetic stays IEEE, no fast-math):
# - LLVM at -O0: the whole suite went from 9 min 34 s to 7 min 15 s on 2 cores;
# - the classic elemental emitters instead of the MLIR fusion emitters: 20 % less CPU
#   (Kim's and Calugi's (2003) reproductions, 66 s against 81 s; docs/testing.md).
# The CLI and benchmarks keep XLA's defaults. A value already in XLA_FLAGS wins.
import xla_emitters  # noqa: E402  (the emitter option, shared with the tests that run without it)

for _flag, _value in (("xla_backend_optimization_level", "0"), (xla_emitters.FLAG, "false")):
    if _flag not in os.environ.get("XLA_FLAGS", ""):
        os.environ["XLA_FLAGS"] = (os.environ.get("XLA_FLAGS", "") + f" --{_flag}={_value}").strip()

# One persistent XLA compilation cache per pytest run, shared by its xdist workers (a worker's
# parent is the controller): a program one worker compiled, the other loads. Fresh per run,
# so timings do not depend on earlier runs. A JAX_COMPILATION_CACHE_DIR already set wins.
import tempfile  # noqa: E402

_run = os.getppid() if "PYTEST_XDIST_WORKER" in os.environ else os.getpid()
_OWN_CACHE = None if "JAX_COMPILATION_CACHE_DIR" in os.environ else os.path.join(tempfile.gettempdir(), f"lookout-test-jax-cache-{_run}")
if _OWN_CACHE is not None:
    os.environ["JAX_COMPILATION_CACHE_DIR"] = _OWN_CACHE
os.environ.setdefault("JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS", "0.5")

import lookout  # noqa: E402  (enables float64 before any test builds arrays)

lookout.configure_cpu(devices=2)  # the CLI's XLA:CPU options, and two devices: batches take the sharded path
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from hypothesis import settings  # noqa: E402

# no wall-clock limits in tests: a first call compiles, and CI machines vary
settings.register_profile("lookout", deadline=None)
settings.load_profile("lookout")

from lookout.models.vessel import NORTHERN_CLIPPER_LENGTH, NORTHERN_CLIPPER_MASS, northern_clipper  # noqa: E402
from lookout.observers import PassiveObserver, injection_gains_from_normalized  # noqa: E402


@pytest.fixture(scope="session")
def paper_observer():
    """The observer of Fossen & Strand (1999), eqs. (58)–(60), gains converted to SI."""
    kappa, lam = injection_gains_from_normalized([0.1, 0.1, 0.01], [0.01, 0.01, 0.001], mass=NORTHERN_CLIPPER_MASS, length=NORTHERN_CLIPPER_LENGTH)
    return PassiveObserver.design(
        northern_clipper(),
        wave_frequency=0.8976,
        wave_damping=0.1,
        notch_damping=1.0,
        cutoff_frequency=1.1,
        velocity_injection_gain=kappa,
        bias_injection_gain=lam,
        bias_time_constant=1000.0,
    )


@pytest.fixture(autouse=True)
def _registry_as_it_was():
    """The kinds a test registers (a plugin it loads) are unregistered after it, with the
    modules that declared them: the other tests on this worker enumerate the kinds."""
    from lookout import declare
    from lookout.scenario import registry

    registry.kinds()  # lookout's own kinds, once
    count = len(declare.DECLARED)
    yield
    for each in declare.DECLARED[count:]:
        sys.modules.pop(each.module, None)
    del declare.DECLARED[count:]


def pytest_sessionfinish(session, exitstatus):
    """The run's own compilation cache is removed at its end, by the process that named
    it (the controller, or a run without workers); one a user set stays."""
    if _OWN_CACHE is not None and "PYTEST_XDIST_WORKER" not in os.environ:
        import shutil

        shutil.rmtree(_OWN_CACHE, ignore_errors=True)


@pytest.fixture
def rng():
    return np.random.default_rng(1234)


# The end-to-end tests that compile the largest programs (a gradient through a whole
# closed loop, a paper's reproduction, every observer on every plant): `make test` runs
# them, `make check` (the loop while one works) leaves them out. Whole files here, single
# tests with @pytest.mark.slow in their own files.
SLOW_FILES = {
    "test_tuning.py",
    "test_tuning_kalman.py",
    "test_tuning_kim.py",
    "test_tuning_wondergem.py",
    "test_tuning_manipulator.py",
    "test_tuning_adaptive_dp.py",
    "test_benchmark.py",
    "test_conformance.py",
    "test_composition_matrix.py",
    "test_thrusters.py",
}
SLOW_FOLDERS = {"papers"}


def pytest_collection_modifyitems(config, items):
    for item in items:
        path = item.path
        if path.name in SLOW_FILES or path.parent.name in SLOW_FOLDERS:
            item.add_marker(pytest.mark.slow)


@pytest.fixture(scope="module", autouse=True)
def _compiled_programs_freed():
    """A worker's compiled programs are dropped after each test file: JAX's caches keep
    every executable a process built, and a worker running half the suite grew to 12 GB
    without this (a file's own tests still share their programs)."""
    yield
    import gc

    import jax

    jax.clear_caches()
    gc.collect()
