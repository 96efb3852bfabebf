"""Which probe updates a client awaits, and the replies read for others (shared by the sync and
asyncio clients; no I/O)."""
from __future__ import annotations

from collections import deque
from typing import Deque, Dict, List, Optional, Union

from . import _wire
from .errors import ServerError
from .types import ProbeReply

Item = Union[ProbeReply, ServerError]


class ProbeBook:
    def __init__(self, endpoint: str, client_id: int) -> None:
        self.endpoint = endpoint
        self.client_id = client_id
        self.sequence = 0
        self.pending: Dict[int, None] = {}  # awaited sequences, oldest first
        self.arrived: Deque[Item] = deque()  # read while waiting for another update
        self.max_outstanding = 1000

    def next_sequence(self) -> int:
        self.sequence += 1
        self.pending[self.sequence] = None
        return self.sequence

    def trim(self) -> None:
        while len(self.pending) > self.max_outstanding:
            del self.pending[next(iter(self.pending))]

    def decode(self, data: bytes) -> Optional[Item]:
        """A reply (or refusal) to an awaited update, no longer awaited after this; None for a
        reply to an update given up on."""
        try:
            reply = _wire.decode_probe_reply(self.endpoint, data, self.client_id, self.pending,
                                             _wire.now_ns())
        except ServerError as e:
            if e.sequence is not None:
                self.pending.pop(e.sequence, None)
            return e
        if reply is not None:
            self.pending.pop(reply.sequence, None)
        return reply

    def take_arrived(self) -> List[ProbeReply]:
        """The replies read so far, oldest first, up to the first refusal (raised when it is
        the oldest)."""
        out: List[ProbeReply] = []
        while self.arrived:
            item = self.arrived[0]
            if isinstance(item, ServerError):
                if out:
                    return out
                self.arrived.popleft()
                raise item
            out.append(item)
            self.arrived.popleft()
        return out

    @property
    def outstanding(self) -> int:
        return len(self.pending) + len(self.arrived)
