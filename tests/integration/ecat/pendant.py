"""A pendant inside the test's network namespace: `pendant.py PORT CMD[,CMD...] WANT_STATE`
sends each command (waiting for its reply) and waits for the state; prints the status."""

import asyncio
import json
import sys
import time

from websockets.asyncio.client import connect


async def main(port, cmds, want):
    # max_queue=None: this pendant stops reading once it has its state, while the gateway goes
    # on sending status at 50 Hz. With websockets' default (16 frames) the library stops reading
    # the socket when its queue is full, so it never sees the gateway's close frame and every
    # exit waited close_timeout (10 s) for it: 80 s of the ecat_run test were spent so.
    async with connect(f"ws://127.0.0.1:{port}/ws", max_queue=None) as ws:
        await ws.send(json.dumps({"type": "hello", "role": "pendant", "client": "ecat test"}))
        seq = 0
        status = None
        for cmd in [c for c in cmds.split(",") if c]:
            seq += 1
            name, *args = cmd.split(":")
            msg = {"type": "command", "seq": seq, "cmd": name}
            if name == "sim":  # sim:KEY=VALUE, as the HMI's simulated-cell panel sends it
                key, value = args[0].split("=")
                msg = {"type": "sim", "seq": seq, "set": {key: int(value) if value.isdigit() else value}}
            elif name == "jog":
                msg.update(axis=int(args[0]), dir=args[1], speed=int(args[2]))
            await ws.send(json.dumps(msg))
            deadline = time.monotonic() + 10
            while time.monotonic() < deadline:
                m = json.loads(await asyncio.wait_for(ws.recv(), 10))
                if m.get("type") in ("reply", "error") and m.get("seq", seq) == seq:
                    print(json.dumps({"answer": m}), file=sys.stderr)
                    break
            await asyncio.sleep(0.3)
        if cmds.split(",")[-1].startswith("jog"):
            # a jog lasts while the pendant keeps asking (hold-to-run, ISO 10218-1 5.8)
            seq_hold = seq
            end = time.monotonic() + 1.5
            while time.monotonic() < end:
                seq_hold += 1
                msg["seq"] = seq_hold
                await ws.send(json.dumps(msg))
                tick = time.monotonic() + 0.04
                while time.monotonic() < tick:
                    try:
                        m = json.loads(await asyncio.wait_for(ws.recv(), 0.02))
                    except asyncio.TimeoutError:
                        continue
                    if m.get("type") == "status":
                        status = m
            print(json.dumps(status))
            return
        deadline = time.monotonic() + 15
        while time.monotonic() < deadline:
            m = json.loads(await asyncio.wait_for(ws.recv(), 10))
            if m.get("type") == "status":
                status = m
                if m["state"] == want or (want.startswith("OPERATIONAL") and m["state"] == "OPERATIONAL"):
                    break
        print(json.dumps(status))


asyncio.run(main(int(sys.argv[1]), sys.argv[2], sys.argv[3]))
