"""The reconnect schedule of the gateway's clients in this repository (adapters/opcua/src/
backoff.ts, issue 23), the same numbers: exponential with equal jitter, 0.5 s doubling to 10 s,
so that every client of a plant does not come back in the same millisecond after a gateway
restart."""

import random as _random

FIRST_RETRY_S = 0.5
MAX_RETRY_S = 10.0


def retry_ceiling_s(failures=1, first=FIRST_RETRY_S, most=MAX_RETRY_S):
    n = max(1, min(int(failures), 30))
    return min(most, first * 2 ** (n - 1))


def retry_delay_s(failures=1, random=_random.random, first=FIRST_RETRY_S, most=MAX_RETRY_S):
    """Drawn evenly from [ceiling / 2, ceiling]: never zero."""
    ceiling = retry_ceiling_s(failures, first, most)
    r = max(0.0, min(random(), 1.0))
    return ceiling / 2 + r * (ceiling / 2)
