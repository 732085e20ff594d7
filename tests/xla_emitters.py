"""A test whose claim is bit-for-bit agreement between programs compiled apart runs with
XLA:CPU's default (fusion) emitters.

The suite compiles with the classic elemental emitters (``tests/conftest.py``: 20 % less
CPU), and with them XLA may round one subcomputation differently in two programs that
contain it (the DP benchmark's measurements, compiled once with each observer, differ in
the last bit of 42 % of the fixes). The CLI and the library keep XLA's defaults, whose
programs agree bit for bit: such a test checks them, in a child process.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

#: The XLA:CPU option, and its value with which the suite compiles (set in tests/conftest.py).
FLAG = "xla_cpu_use_fusion_emitters"
CLASSIC = f"--{FLAG}=false"


def ran_with_fusion_emitters(nodeid: str) -> bool:
    """True when this process compiles with the classic emitters: then the test ``nodeid``
    has run (and passed, or this fails with its output) in a child process with XLA's
    fusion emitters, and the caller returns. False: the caller runs the test itself."""
    flags = os.environ.get("XLA_FLAGS", "")
    if CLASSIC not in flags:
        return False
    environment = {k: v for k, v in os.environ.items() if not k.startswith("PYTEST_")}
    environment["XLA_FLAGS"] = flags.replace(CLASSIC, f"--{FLAG}=true")
    child = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-p", "no:xdist", nodeid],
        cwd=Path(__file__).parent.parent,
        env=environment,
        capture_output=True,
        text=True,
    )
    assert child.returncode == 0, f"{nodeid} with XLA's fusion emitters:\n{child.stdout[-4000:]}{child.stderr[-2000:]}"
    return True
