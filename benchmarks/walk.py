"""The walk of ``lookout run FILE``: the lookout frames on the stack when the engine first
samples the scenario (sensors read the plant), from the command down, and the number of
returns to a module the walk had already left.

    python benchmarks/walk.py [FILE]      (default examples/dp-observer.toml)

docs/architecture.md shows what it prints. JAX's own frames between lookout's (``jit``,
``scan``) are left out; each line is ``file:function`` relative to src/lookout.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import lookout

ROOT = Path(lookout.__file__).parent
FIRST_SAMPLE = {"_sample", "sample_measurements"}  # the engine's function that samples the sensors


class _Found(Exception):
    pass


def walk(argv: list[str]) -> tuple[list[tuple[str, str]], list[tuple[str, str]]]:
    """The stack at the first sample, and the calls the command's function makes into
    lookout's other modules before it, in order (each ``(file, function)``; the
    command's own helpers in studies/cli.py are its steps, not stops)."""
    stack: list[tuple[str, str]] = []
    steps: list[tuple[str, str]] = []
    command: list = []

    def where(code) -> str | None:
        path = Path(code.co_filename)
        return str(path.relative_to(ROOT)) if ROOT in path.parents else None

    def tracer(frame, event, arg):
        if event != "call":
            return None
        code = frame.f_code
        if not command and code.co_name == "run" and where(code) == "studies/cli.py":
            command.append(frame)
        elif command and frame.f_back is command[0] and where(code) not in (None, "studies/cli.py"):
            steps.append((where(code), code.co_name))
        if code.co_name in FIRST_SAMPLE and frame.f_globals.get("__name__", "").startswith("lookout.sim"):
            here = frame
            while here is not None:
                path = Path(here.f_code.co_filename)
                if ROOT in path.parents:
                    stack.append((str(path.relative_to(ROOT)), here.f_code.co_name))
                here = here.f_back
            raise _Found
        return None

    from lookout.cli import main

    sys.setprofile(None)
    sys.settrace(tracer)
    try:
        main(argv)
    except _Found:
        pass
    finally:
        sys.settrace(None)
    return stack[::-1], steps


def returns(stack: list[tuple[str, str]]) -> list[str]:
    """The modules the walk comes back to after leaving them."""
    left, back, previous = set(), [], None
    for module, _ in stack:
        if module != previous:
            if module in left:
                back.append(module)
            if previous is not None:
                left.add(previous)
            previous = module
    return back


if __name__ == "__main__":
    file = sys.argv[1] if len(sys.argv) > 1 else "examples/dp-observer.toml"
    with tempfile.TemporaryDirectory() as out:
        stack, steps = walk(["run", file, "--out", out])
    if not stack:
        sys.exit("the run never reached the engine's sampling")
    print("the command's calls, in order, up to the first sample:")
    for number, (module, function) in enumerate(steps, 1):
        print(f"{number}. {module}:{function}")
    back = returns(steps)
    print(f"returns to a module already left: {len(back)}" + (f" ({', '.join(back)})" if back else ""))
    print("the stack at the first sample:")
    for number, (module, function) in enumerate(stack, 1):
        print(f"{number}. {module}:{function}")
    back = returns(stack)
    print(f"returns to a module already left: {len(back)}" + (f" ({', '.join(back)})" if back else ""))
