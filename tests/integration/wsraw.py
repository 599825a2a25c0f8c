"""The raw RFC 6455 pieces of the load tests' clients (test_load.py, test_burst.py): the
`websockets` library is too slow for hundreds of clients in one process, so these clients
frame by hand. Only what a client needs: masked frames out, unmasked frames in."""

import os


def masked(opcode, payload):
    """A client's frame (FIN set, masked as RFC 6455 5.3 requires), payload < 64 KiB."""
    mask = os.urandom(4)
    head = bytes([0x80 | opcode, 0x80 | len(payload)]) if len(payload) < 126 else \
        bytes([0x80 | opcode, 0x80 | 126]) + len(payload).to_bytes(2, "big")
    return head + mask + bytes(b ^ mask[i % 4] for i, b in enumerate(payload))


def frame_at(buf, pos):
    """The server's frame that starts at buf[pos]: (opcode, payload start, payload length),
    or None while it is not complete in buf."""
    n = len(buf)
    if n - pos < 2:
        return None
    opcode, ln, hl = buf[pos] & 0x0F, buf[pos + 1] & 0x7F, 2
    if ln == 126:
        if n - pos < 4:
            return None
        ln, hl = int.from_bytes(buf[pos + 2:pos + 4], "big"), 4
    elif ln == 127:
        if n - pos < 10:
            return None
        ln, hl = int.from_bytes(buf[pos + 2:pos + 10], "big"), 10
    if n - pos < hl + ln:
        return None
    return opcode, pos + hl, ln
