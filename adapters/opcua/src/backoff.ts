// The reconnect schedule (issue 23) of the gateway's clients in this repository, the OPC UA
// adapter and the HMI (hmi/src/connection.ts imports this file): exponential with jitter, so that every client of a
// plant does not come back in the same millisecond after a gateway restart, or after the
// gateway refused it in a burst (HTTP 503 + Retry-After, close 1013 "try again later"),
// and get refused again.
//
// Plain JavaScript syntax on purpose (types come from the defaults): adapters/opcua/tests/
// backoff.test.mjs runs this very file under `node --test` without a TypeScript build.

export const FIRST_RETRY_MS = 500;
export const MAX_RETRY_MS = 10000;

/** The ceiling after `failures` failed attempts in a row (>= 1): doubles from
 * FIRST_RETRY_MS up to MAX_RETRY_MS. */
export function retryCeilingMs(failures = 1, firstMs = FIRST_RETRY_MS, maxMs = MAX_RETRY_MS) {
  const n = Math.max(1, Math.min(Math.floor(failures), 30));
  return Math.min(maxMs, firstMs * 2 ** (n - 1));
}

/** The delay before the next attempt: drawn evenly from [ceiling / 2, ceiling] ("equal
 * jitter": never zero, and clients that failed together spread over half the ceiling).
 * `random` returns a number in [0, 1). */
export function retryDelayMs(failures = 1, random = Math.random, firstMs = FIRST_RETRY_MS, maxMs = MAX_RETRY_MS) {
  const ceiling = retryCeilingMs(failures, firstMs, maxMs);
  const r = Math.max(0, Math.min(random(), 1));
  return Math.round(ceiling / 2 + r * (ceiling / 2));
}
