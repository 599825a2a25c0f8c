// The reconnect schedule (issue 23): exponential, with jitter, so that the clients of a
// gateway that restarts, or that refused them (HTTP 503 + Retry-After, close 1013 "try
// again later"), do not all come back in the same millisecond and get refused again.
using System;

namespace SafeState.Client
{
    /// <summary>Jittered exponential back-off: the ceiling doubles with every failed attempt,
    /// from <c>first</c> up to <c>max</c>; the delay is drawn evenly from [ceiling / 2, ceiling]
    /// ("equal jitter": never zero, and two clients that failed together spread over half the
    /// ceiling).</summary>
    public static class Backoff
    {
        /// <summary>The ceiling before attempt number <paramref name="failures"/> + 1
        /// (<paramref name="failures"/>: attempts that failed so far, counted from 1). A
        /// <c>max</c> below <c>first</c> is taken as <c>first</c>; a <c>first</c> of zero or less
        /// means no delay (ClientOptions as the application set them: never an exception in
        /// the reconnect loop).</summary>
        public static TimeSpan Ceiling(int failures, TimeSpan first, TimeSpan max)
        {
            if (first <= TimeSpan.Zero) return TimeSpan.Zero;
            if (max < first) max = first;
            long ticks = first.Ticks;
            for (int i = 1; i < failures && ticks < max.Ticks; i++) ticks *= 2;
            return TimeSpan.FromTicks(Math.Min(ticks, max.Ticks));
        }

        /// <summary>The delay before the next attempt; <paramref name="random"/> in [0, 1).</summary>
        public static TimeSpan Delay(int failures, TimeSpan first, TimeSpan max, double random)
        {
            random = Math.Max(0.0, Math.Min(random, 1.0));
            long ceiling = Ceiling(failures, first, max).Ticks;
            return TimeSpan.FromTicks(ceiling / 2 + (long)(random * (ceiling - ceiling / 2)));
        }
    }
}
