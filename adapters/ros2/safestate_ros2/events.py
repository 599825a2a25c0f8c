"""Each event log entry once, in order, none lost across a reconnect (issue 39, ~/events).

The gateway pushes each event to every connected client (protocol.md "event") and keeps them
all in its log, served by GET /api/events?after=ID oldest first (at most 500 a page). The
gateway writes an event to the log before it sends it to anyone ("Nothing lost"), so:

1. after each welcome, live events are held back (`hold`) while the log is read from the
   last id published (`catch_up` with each page), then the held ones are released in id
   order (`release`), skipping what the log already gave;
2. the first time, with no id yet, the log is read only to find where it ends: what happened
   before the adapter started is history, not news (parameter events_after says otherwise).

Pure bookkeeping, no I/O: the caller publishes what `offer`, `catch_up` and `release` return.
"""


def valid_event(e):
    """An event message as protocol.md has it: a positive integer id, an integer t, string
    time and kind, an object data. Anything else is dropped (and counted by the caller)."""
    return (isinstance(e, dict) and isinstance(e.get("id"), int) and not isinstance(e.get("id"), bool)
            and e["id"] > 0 and isinstance(e.get("t"), int) and isinstance(e.get("time"), str)
            and isinstance(e.get("kind"), str) and isinstance(e.get("data", {}), (dict, type(None))))


class EventSequencer:
    def __init__(self, after=None):
        # The id of the last event published; None: not known yet (skip the history).
        self.last = after
        self._holding = False
        self._held = []

    @property
    def primed(self):
        return self.last is not None

    def hold(self):
        """A new connection: hold live events until the log has been read."""
        self._holding = True
        self._held = []

    def offer(self, e):
        """A live event: the list to publish now (empty while held, or a repeat)."""
        if not valid_event(e):
            return []
        if self._holding:
            self._held.append(e)
            return []
        return self._take([e])

    def catch_up(self, page, publish=True):
        """One page of GET /api/events (oldest first): the events to publish. With
        publish=False (the first connection) the page only moves the mark to its end."""
        events = sorted((e for e in page if valid_event(e)), key=lambda e: e["id"])
        if not publish:
            if events:
                self.last = max(self.last or 0, events[-1]["id"])
            return []
        return self._take(events)

    def start_empty(self):
        """The log is empty or its end was found: nothing before this is news."""
        if self.last is None:
            self.last = 0

    def release(self):
        """The log has been read: the held live events, in order, without repeats."""
        self._holding = False
        held, self._held = self._held, []
        return self._take(sorted(held, key=lambda e: e["id"]))

    def _take(self, events):
        out = []
        for e in events:
            if self.last is not None and e["id"] <= self.last:
                continue  # already published (the log and the live stream overlap)
            self.last = e["id"]
            out.append(e)
        return out
