"""A scenario's observer on sensor data: live streams and recorded logs.

:class:`Session` steps the observer on readings as they arrive, with the rules of
:class:`GatedObserver` (hold, timeout, wild-point gate) inside the compiled step;
:func:`replay` and :func:`live` feed it from a log or a stream (docs/live.md).

The names below are imported when first used (PEP 562), so that the command's
modules, which import :mod:`lookout.live.cli`, do not import JAX through this package.
"""

#: The public names, name -> the module that defines it.
_PUBLIC = {
    "GatedObserver": "lookout.live.gate",
    "live": "lookout.live.run",
    "open_source": "lookout.live.run",
    "replay": "lookout.live.run",
    "Block": "lookout.live.session",
    "Gates": "lookout.live.options",
    "Session": "lookout.live.session",
}
__all__ = list(_PUBLIC)


def __getattr__(name: str):
    if name not in _PUBLIC:
        raise AttributeError(f"module 'lookout.live' has no attribute {name!r}")
    import importlib

    value = getattr(importlib.import_module(_PUBLIC[name]), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(__all__))
