"""The robot drivers' link: :mod:`bench.serial_link`'s framing (re-exported here, where the drivers import it) and
:class:`WireProtocolError`, the only error the wire parsers raise (a malformed frame).
"""

from __future__ import annotations

from bench.errors import LinkError
from bench.serial_link import Deadline, FramedLink, open_port

__all__ = ["Deadline", "FramedLink", "WireProtocolError", "open_port"]


class WireProtocolError(LinkError):
    """A frame that does not follow the wire protocol (bad checksum, unknown reply, wrong field count)."""
