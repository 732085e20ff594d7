"""A scenario's observer on sensor data: live streams and recorded logs.

:class:`Session` steps the observer on readings as they arrive, with the rules of
:class:`GatedObserver` (hold, timeout, wild-point gate) inside the compiled step;
:func:`replay` and :func:`live` feed it from a log or a stream (docs/live.md).
"""

from lookout.live.gate import GatedObserver as GatedObserver
from lookout.live.run import live as live
from lookout.live.run import open_source as open_source
from lookout.live.run import replay as replay
from lookout.live.session import Block as Block
from lookout.live.session import Gates as Gates
from lookout.live.session import Session as Session
