"""What importing lookout does to the process, and what configure_cpu does."""

import subprocess
import sys


def _run(code: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env={"PATH": "/usr/bin:/bin"})


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
