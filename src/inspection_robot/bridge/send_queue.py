"""One websocket client's outgoing messages, bounded by a byte budget (:class:`SendQueue`).

Kept apart from the transport (server.py, handler.py) because it is bookkeeping only: what is
queued, handed to the socket, replaced under a queue_length or refused over budget, with no socket
or event loop, so its unit tests drive it with a fake clock. The policy it carries out (budget,
grace, drop warnings) is described in server.py's docstring.
"""
import collections
import time


def frames_size(frames):
    return sum(len(frame) for frame in frames)


class SendQueue(object):
    """Outgoing messages (each a list of frames) of one client, bounded by a byte budget.

    ``put(frames, key, limit, droppable)``: replies (``droppable=False``) are always queued and sent
    first. A topic message (``key`` = topic) with a ``limit`` (the subscription's queue_length)
    keeps only the newest ``limit`` messages of that key waiting, as rosbridge's queue_length does
    (``limit_dropped`` counts those). Otherwise a topic message is refused only when the bytes
    held for the client (queued plus handed to the socket and not yet written) would pass
    ``budget``: it is then counted in ``dropped[key]`` and put() returns False. A message larger
    than the whole budget still goes when nothing else is held. ``over_since`` is the clock time
    the client went over budget (None while under it).
    """

    def __init__(self, budget, clock=time.monotonic):
        self.budget = max(1, int(budget))
        self._clock = clock
        self._replies = collections.deque()  # (frames, size)
        self._topics = collections.deque()   # entries: [frames, key, alive, size]
        self._by_key = {}                    # key -> deque of entries (keys with a limit only)
        self._alive = 0
        self.queued_bytes = 0
        self.in_flight = 0
        self.dropped = collections.Counter()  # key -> topic messages refused over budget
        self.limit_dropped = 0                # topic messages replaced under their queue_length
        self.discarded = 0                    # topic messages still queued when the client was closed
        self.over_since = None

    def __len__(self):
        return len(self._replies) + self._alive

    @property
    def held_bytes(self):
        return self.queued_bytes + self.in_flight

    def put(self, frames, key=None, limit=None, droppable=True):
        """Queue one message; False when a topic message was refused (over budget)."""
        size = frames_size(frames)
        if not droppable:
            self._replies.append((frames, size))
            self.queued_bytes += size
            self._check_budget()
            return True
        if self.held_bytes + size > self.budget and self.held_bytes > 0 and not limit:
            self.dropped[key] += 1
            if self.over_since is None:
                self.over_since = self._clock()
            return False
        entry = [frames, key, True, size]
        self._topics.append(entry)
        self._alive += 1
        self.queued_bytes += size
        if key is not None and limit:
            per_key = self._by_key.get(key)
            if per_key is None:
                per_key = self._by_key[key] = collections.deque()
            per_key.append(entry)
            self._trim(key, per_key)
            while len(per_key) > limit:
                self._kill(per_key.popleft())
                self.limit_dropped += 1
            self._prune()
        self._check_budget()
        return True

    def _check_budget(self):
        if self.held_bytes > self.budget:
            if self.over_since is None:
                self.over_since = self._clock()
        elif not self.dropped or self.held_bytes < self.budget // 2:
            # under budget again: after drops only once half of it is free, so a client hovering
            # at the edge is not told "recovered" for each message
            self.over_since = None

    def _kill(self, entry):
        if entry[2]:
            entry[2] = False
            self._alive -= 1
            self.queued_bytes -= entry[3]

    def _trim(self, key, per_key):
        # dead entries of a key are always its oldest ones: drop that prefix
        while per_key and not per_key[0][2]:
            per_key.popleft()
        if not per_key:
            del self._by_key[key]

    def _prune(self):
        while self._topics and not self._topics[0][2]:
            self._topics.popleft()

    def pop(self):
        """The next message's frames (replies first), or None when empty; its bytes go in flight."""
        if self._replies:
            frames, size = self._replies.popleft()
        else:
            self._prune()
            if not self._topics:
                return None
            entry = self._topics.popleft()
            frames, size = entry[0], entry[3]
            entry[2] = False
            self._alive -= 1
            if self._by_key and entry[1] in self._by_key:
                self._trim(entry[1], self._by_key[entry[1]])
        self.queued_bytes -= size
        self.in_flight += size
        return frames

    def take_replies(self):
        """Every queued reply's frames, removed from the queue (sent ahead of a close)."""
        frames = []
        while self._replies:
            reply, size = self._replies.popleft()
            frames.extend(reply)
            self.queued_bytes -= size
        return frames

    def discard_topics(self):
        """Drop every topic message still queued (the client is being closed); returns how many.
        ``discarded`` counts them; the close reason tells them with the refused ones."""
        count = self._alive
        for entry in self._topics:
            self._kill(entry)
        self._topics.clear()
        self._by_key.clear()
        self.discarded += count
        return count

    def written(self, size):
        """``size`` bytes handed out by pop() have been written to the socket."""
        self.in_flight -= size
        self._check_budget()
