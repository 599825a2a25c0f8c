"""The adapter's only path to the core: a `remote` client of the gateway's WebSocket protocol
(shared/spec/protocol.md), as the OPC UA adapter is (adapters/opcua/src/gateway_client.ts). It is
no more privileged than a PLC on the same socket: AUTO only, never `reset`.

Runs in an asyncio loop of its own thread; the callbacks (on_status, on_events, on_up, on_down,
on_robot, on_safety, on_alarms) are called in that thread.
"""

import asyncio
import json
import time
import urllib.error
import urllib.request

from websockets.asyncio.client import connect as ws_connect
from websockets.exceptions import ConnectionClosed, InvalidHandshake, InvalidURI

from .backoff import retry_delay_s
from .events import EventSequencer

# Status comes at 50 Hz. Silence makes the state unknown after node.STATUS_SILENCE_S (0.6 s);
# the connection is given up only after RECONNECT_SILENCE_S, so that a host that stalls for a
# moment costs a moment of `unknown`, not the session and the commands in flight.
RECONNECT_SILENCE_S = 3.0
REPLY_TIMEOUT_S = 3.0  # the core answers in the cycle it takes a command (SPEC §5); a reset 50 cycles
HTTP_TIMEOUT_S = 2.0
EVENTS_PAGE = 500  # protocol.md: at most 500 events per page


class Lost(Exception):
    pass


class Gateway:
    def __init__(self, host, port, token, client, log, events_after=None):
        self.url = f"ws://{host}:{port}/ws"
        self.http = f"http://{host}:{port}"
        self.token = token
        self.client = client
        self.log = log
        self.events = EventSequencer(events_after)
        self.on_status = lambda s: None
        self.on_events = lambda evs: None
        self.on_up = lambda: None
        self.on_down = lambda why: None
        self.on_robot = lambda robot: None
        self.on_safety = lambda cfg: None
        self.on_alarms = lambda rows: None
        self.live = False
        self.connections = 0  # welcomes so far
        self.dropped_events = 0
        self._ws = None
        self._seq = 0
        self._pending = {}
        self._failures = 0
        self._last_status = 0.0
        self._stopping = False
        self._alarm_names = None
        self._alarms_due = 0.0

    # ------------------------------------------------------------------ public (asyncio thread)
    async def run(self):
        while not self._stopping:
            why = await self._session()
            self._lost(why)
            if self._stopping:
                break
            self._failures += 1
            delay = retry_delay_s(self._failures)
            self.log.info(f"gateway {self.url}: {why}; reconnecting in {delay:.1f} s")
            await asyncio.sleep(delay)

    async def stop(self):
        self._stopping = True
        if self._ws is not None:
            await self._ws.close()

    async def command(self, cmd):
        """The SafeState result name of `cmd` (SPEC §5), or GATEWAY_UNAVAILABLE / TIMEOUT.
        Sent once: never retried (a retried start is a second start)."""
        if self._ws is None or not self.live:
            return "GATEWAY_UNAVAILABLE"
        self._seq += 1
        seq = self._seq
        fut = asyncio.get_running_loop().create_future()
        self._pending[seq] = fut
        try:
            await self._ws.send(json.dumps({"type": "command", "seq": seq, "cmd": cmd}))
            return await asyncio.wait_for(fut, REPLY_TIMEOUT_S)
        except asyncio.TimeoutError:
            return "TIMEOUT"
        except ConnectionClosed:
            return "GATEWAY_UNAVAILABLE"
        finally:
            self._pending.pop(seq, None)

    # ------------------------------------------------------------------ one connection
    async def _session(self):
        try:
            # A non-browser client sends no Origin header (protocol.md "Who may connect").
            async with ws_connect(self.url, open_timeout=2, close_timeout=1, max_size=2 ** 22,
                                  ping_interval=None) as ws:
                self._ws = ws
                hello = {"type": "hello", "role": "remote", "client": self.client}
                if self.token:
                    hello["token"] = self.token
                await ws.send(json.dumps(hello))
                welcome = await self._welcome(ws)
                if welcome is not None:
                    return welcome
                self._failures = 0
                self.connections += 1
                self.events.hold()
                self._last_status = time.monotonic()
                reader = asyncio.create_task(self._reader(ws))
                watchdog = asyncio.create_task(self._watchdog())
                try:
                    await self._fetch_descriptions()
                    await self._catch_up()
                    self._publish(self.events.release())
                    done, _ = await asyncio.wait({reader, watchdog}, return_when=asyncio.FIRST_COMPLETED)
                    return next(iter(done)).result()
                finally:
                    for t in (reader, watchdog):
                        t.cancel()
                    await asyncio.gather(reader, watchdog, return_exceptions=True)
        except Lost as e:
            return str(e)
        except (OSError, asyncio.TimeoutError, InvalidHandshake, InvalidURI, ConnectionClosed) as e:
            return f"connection failed ({type(e).__name__}: {e})"
        finally:
            self._ws = None

    async def _welcome(self, ws):
        """None after a welcome; the reason otherwise."""
        try:
            async with asyncio.timeout(5):
                while True:
                    m = _parse(await ws.recv())
                    if m is None:
                        continue
                    if m.get("type") == "welcome":
                        self.log.info(f"gateway {self.url}: welcome as remote ({m.get('server')})")
                        return None
                    if m.get("type") == "error":
                        code = m.get("code")
                        # The token never goes to the log, only whether one was sent.
                        return f"refused: {code} ({m.get('detail', '')}; token {'sent' if self.token else 'not set'})"
        except asyncio.TimeoutError:
            return "no welcome within 5 s"

    async def _reader(self, ws):
        try:
            async for raw in ws:
                m = _parse(raw)
                if m is None:
                    continue
                kind = m.get("type")
                if kind == "status":
                    self._last_status = time.monotonic()
                    if not self.live:
                        self.live = True
                        self.on_up()
                    self.on_status(m)
                    self._maybe_fetch_alarms(m)
                elif kind == "event":
                    self._publish(self.events.offer(m))
                elif kind == "reply":
                    fut = self._pending.get(m.get("seq"))
                    if fut is not None and not fut.done():
                        fut.set_result(str(m.get("result")))
                elif kind == "error":
                    self.log.warning(f"gateway error {m.get('code')}: {m.get('detail', '')}")
        except ConnectionClosed:
            pass
        return "connection closed"

    async def _watchdog(self):
        while True:
            await asyncio.sleep(0.05)
            if time.monotonic() - self._last_status > RECONNECT_SILENCE_S:
                return f"no status for {RECONNECT_SILENCE_S:g} s"

    def _lost(self, why):
        for fut in self._pending.values():
            if not fut.done():
                fut.set_result("GATEWAY_UNAVAILABLE")
        self._pending.clear()
        if self.live:
            self.live = False
        self.on_down(why)

    # ------------------------------------------------------------------ the log and descriptions
    def _publish(self, events):
        if events:
            self.on_events(events)

    async def _catch_up(self):
        """Everything the log holds after the last id published (or, the first time, just
        where it ends); raises Lost when the gateway does not answer."""
        first = not self.events.primed
        after = self.events.last or 0
        while True:
            page = await self._get(f"/api/events?after={after}&limit={EVENTS_PAGE}")
            if not isinstance(page, list):
                raise Lost(f"GET /api/events?after={after}: no list")
            self._publish(self.events.catch_up(page, publish=not first))
            ids = [e["id"] for e in page if isinstance(e, dict) and isinstance(e.get("id"), int)]
            if len(page) < EVENTS_PAGE or not ids:
                break
            after = max(ids)
        self.events.start_empty()

    async def _fetch_descriptions(self):
        # Called with None too (no description served): joint_states wait for this call.
        self.on_robot(await self._get("/api/robot", required=False))
        safety = await self._get("/api/safety", required=False)
        if safety is not None:
            self.on_safety(safety)

    def _maybe_fetch_alarms(self, status):
        names = status.get("alarms")
        now = time.monotonic()
        # On every change of the active set, and every 2 s while any is active (details move).
        if names != self._alarm_names or (names and now >= self._alarms_due):
            self._alarm_names = names
            self._alarms_due = now + 2.0
            if names:
                asyncio.get_running_loop().create_task(self._fetch_alarms())
            else:
                self.on_alarms([])

    async def _fetch_alarms(self):
        rows = await self._get("/api/alarms", required=False)
        if isinstance(rows, list):
            self.on_alarms(rows)

    async def _get(self, path, required=True):
        try:
            return await asyncio.to_thread(self._get_blocking, path)
        except (OSError, ValueError, urllib.error.URLError) as e:
            if required:
                raise Lost(f"GET {path}: {e}") from e
            return None

    def _get_blocking(self, path):
        req = urllib.request.Request(self.http + path)
        if self.token:
            req.add_header("Authorization", f"Bearer {self.token}")
        with urllib.request.urlopen(req, timeout=HTTP_TIMEOUT_S) as r:
            if r.status != 200:
                raise ValueError(f"HTTP {r.status}")
            return json.loads(r.read().decode("utf-8"))


def _parse(raw):
    try:
        m = json.loads(raw)
    except (TypeError, ValueError):
        return None
    return m if isinstance(m, dict) else None
