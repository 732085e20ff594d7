"""What importing lookout does to the process, and what configure_cpu does."""

import os
import subprocess
import sys

import pytest


def _run(code: str) -> subprocess.CompletedProcess:
    """``code`` in a fresh Python with no environment but PATH (and PYTHONPATH, where the
    sources under test are found through it)."""
    env = {"PATH": "/usr/bin:/bin"} | ({"PYTHONPATH": os.environ["PYTHONPATH"]} if "PYTHONPATH" in os.environ else {})
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)


def test_importing_lookout_changes_no_environment_variable_and_enables_float64():
    result = _run(
        "import os, jax; before = dict(os.environ); import lookout; "
        "assert dict(os.environ) == before, set(os.environ.items()) ^ set(before.items()); "
        "assert 'XLA_FLAGS' not in os.environ; assert jax.config.jax_enable_x64; print('ok')"
    )
    assert result.returncode == 0 and result.stdout.strip() == "ok", result.stderr


def test_configure_cpu_sets_the_loop_threshold_and_device_count_and_keeps_the_users_options():
    result = _run(
        "import os; os.environ['XLA_FLAGS'] = '--xla_force_host_platform_device_count=3'; import lookout; "
        "lookout.configure_cpu(devices=2); import jax; print(os.environ['XLA_FLAGS']); print(len(jax.devices()))"
    )
    flags, devices = result.stdout.strip().splitlines()
    assert "xla_cpu_small_while_loop_byte_threshold=1000000" in flags and devices == "3", result.stderr


def test_importing_lookout_and_its_command_loads_no_model_and_starts_no_backend():
    """The XLA options of configure_cpu take effect only if nothing has started JAX's
    backend before: importing lookout, and the command's module, must not (a module that
    built an array at import once made the command run every batch on one core). The
    public names are imported when first used, so `lookout --version` stays quick."""
    result = _run(
        "import sys, lookout, lookout.cli; from jax._src import xla_bridge; "
        "assert not xla_bridge.backends_are_initialized(); "
        "assert 'lookout.observers' not in sys.modules and 'lookout.papers.kim_2002' not in sys.modules, sorted(m for m in sys.modules if m.startswith('lookout')); "
        "lookout.configure_cpu(devices=2); import jax; assert len(jax.devices()) == 2; "
        "assert lookout.PassiveObserver.__name__ == 'PassiveObserver' and 'filter' in dir(lookout); print('ok')"
    )
    assert result.returncode == 0 and result.stdout.strip() == "ok", result.stderr


def test_configure_cpu_after_the_backend_started_says_it_is_too_late():
    result = _run("import warnings, jax.numpy as jnp, lookout; jnp.zeros(1); warnings.simplefilter('error'); lookout.configure_cpu()")
    assert result.returncode != 0 and "RuntimeWarning: lookout.configure_cpu: JAX's backend has already started" in result.stderr, result.stderr


@pytest.mark.slow
def test_every_reproduction_is_named_in_the_catalog_without_importing_it():
    result = _run(
        "import sys; from lookout.papers import CATALOG, REPRODUCTIONS; "
        "assert not any(m.startswith('lookout.papers.') and m != 'lookout.papers' for m in sys.modules); "
        "assert all(REPRODUCTIONS[name].name == name and REPRODUCTIONS[name].title == entry.title for name, entry in CATALOG.items()); print(len(CATALOG))"
    )
    assert result.returncode == 0 and result.stdout.strip() == "9", result.stderr


def test_the_studies_commands_do_not_import_the_main_command():
    """lookout.cli registers the studies' commands; they share helpers through
    lookout._commandline, never by importing lookout.cli back (no import cycle)."""
    result = _run(
        "import sys, lookout.studies.cli, lookout.studies.execute; assert 'lookout.cli' not in sys.modules, 'lookout.cli imported'; print('ok')"
    )
    assert result.returncode == 0 and result.stdout.strip() == "ok", result.stderr


@pytest.mark.parametrize(
    "imports",
    [
        "import lookout; import jax.numpy as jnp",
        "import lookout; from jax import numpy as jnp",
        "import lookout, importlib; jnp = importlib.import_module('jax.numpy')",
        "import jax; import lookout; import jax.numpy as jnp",
        "from lookout.models.vessel import northern_clipper; import jax.numpy as jnp",
        "import lookout; lookout.simulate; import jax.numpy as jnp",
    ],
)
@pytest.mark.slow
def test_jax_computes_in_float64_whichever_of_lookout_and_jax_is_imported_first(imports):
    """Importing lookout does not import JAX; float64 is on as soon as JAX is imported,
    by whoever imports it, and JAX's package loads as it would (its resources found)."""
    result = _run(
        imports + "; import jax, importlib.resources; assert importlib.resources.files(jax).joinpath('__init__.py').is_file(); "
        "print(jnp.zeros(()).dtype, jnp.asarray(0.1).dtype, jnp.arange(3.0).dtype, jax.config.jax_enable_x64)"
    )
    assert result.returncode == 0, result.stderr
    assert result.stdout.split() == ["float64"] * 3 + ["True"]


def test_importing_lookout_imports_neither_jax_nor_numpy_and_leaves_no_hook_once_jax_is_in():
    result = _run(
        "import sys; import lookout; "
        "assert not {'jax', 'numpy'} & set(sys.modules), sorted({'jax', 'numpy'} & set(sys.modules)); "
        "hooks = lambda: [type(f).__name__ for f in sys.meta_path if type(f).__module__ == 'lookout']; "
        "assert len(hooks()) == 1, hooks(); import importlib; importlib.reload(lookout); assert len(hooks()) == 1, hooks(); "
        "import jax; assert hooks() == [], hooks(); print(lookout.__version__)"
    )
    assert result.returncode == 0 and result.stdout.strip(), result.stderr
