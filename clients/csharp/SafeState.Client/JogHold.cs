// Hold-to-run jogging (ISO 10218-1 5.8.3, hold-to-run in T1): while the operator holds the
// button, `jog` is repeated every ClientOptions.JogKeepAlive, well inside the core's
// jog_timeout_ms, so the core's keep-alive monitor (SPEC rule 7) sees a live link. Release
// ends the repeats and sends `jog_stop`. The hold ends by itself, for good, when a repeat is
// refused or fails, or the link is lost: it is never resumed after a reconnect, the operator
// must press again.
using System;
using System.Threading;
using System.Threading.Tasks;

namespace SafeState.Client
{
    public sealed class JogHold : IDisposable
    {
        private readonly SafeStateClient client;
        private readonly Command jog;
        private readonly TimeSpan period;
        private readonly CancellationTokenSource stop = new CancellationTokenSource();
        private Task loop;
        private int ended;
        private int released;

        internal JogHold(SafeStateClient client, Command jog, TimeSpan period)
        {
            this.client = client;
            this.jog = jog;
            this.period = period;
        }

        /// <summary>The first `jog`: its seq and reply (e.g. OK, ENABLING_NOT_HELD, JOG_NOT_IN_AUTO).</summary>
        public PendingCommand FirstCommand { get; private set; }
        public Task<Result> First { get { return FirstCommand.Reply; } }
        /// <summary>The `jog_stop` sent by Release, once released.</summary>
        public PendingCommand StopCommand { get; private set; }
        /// <summary>True while the keep-alive is being sent.</summary>
        public bool Active { get { return Volatile.Read(ref ended) == 0; } }
        /// <summary>Why the hold ended by itself; null while active or after Release.</summary>
        public string EndReason { get; private set; }
        /// <summary>How many `jog` commands this hold has sent (the first and the repeats).</summary>
        public int Sent { get { return Volatile.Read(ref sentCount); } }
        private int sentCount;

        /// <summary>Raised once when the hold ends by itself (not on Release).</summary>
        public event EventHandler<string> Ended;

        internal void Begin()
        {
            FirstCommand = Send();
            loop = Task.Run(() => Loop());
        }

        private PendingCommand Send()
        {
            Interlocked.Increment(ref sentCount);
            return client.Submit(jog);
        }

        private async Task Loop()
        {
            if (!Check(await Outcome(First).ConfigureAwait(false), "the first jog")) return;
            while (!stop.IsCancellationRequested)
            {
                try
                {
                    await Task.Delay(period, stop.Token).ConfigureAwait(false);
                }
                catch (OperationCanceledException)
                {
                    return;
                }
                if (!Active) return;
                Task<Result> t = Send().Reply;
                _ = t.ContinueWith(r => Check(Outcome(r).Result, "a jog keep-alive"), TaskContinuationOptions.ExecuteSynchronously);
            }
        }

        private static async Task<string> Outcome(Task<Result> t)
        {
            try
            {
                Result r = await t.ConfigureAwait(false);
                return r == Result.OK ? null : Wire.Name(r);
            }
            catch (Exception e)
            {
                return e.Message;
            }
        }

        private bool Check(string problem, string what)
        {
            if (problem == null) return true;
            End(what + " failed: " + problem);
            return false;
        }

        internal void LinkLost(string why)
        {
            End(why);
        }

        private void End(string why)
        {
            bool byRelease;
            lock (stop)
            {
                if (ended != 0) return;
                byRelease = Volatile.Read(ref released) != 0;
                if (!byRelease) EndReason = why;  // set before Active turns false: a reader of Active sees it
                Volatile.Write(ref ended, 1);
            }
            stop.Cancel();
            client.Forget(this);
            if (byRelease) return;
            client.Report(ClientErrorKind.JogStopped, "jog " + jog.Axis + " " + jog.Dir + " stopped: " + why);
            EventHandler<string> h = Ended;
            if (h != null)
            {
                try { h(this, why); } catch (Exception) { /* an application handler must not break the client */ }
            }
        }

        /// <summary>The button was released: stop the repeats and send `jog_stop`.
        /// Completes with the jog_stop reply (fails if the link is gone: the core's keep-alive
        /// timeout then stops the jog on its own within jog_timeout_ms).</summary>
        public async Task<Result> ReleaseAsync()
        {
            Interlocked.Exchange(ref released, 1);
            End(null);
            if (loop != null)
            {
                try { await loop.ConfigureAwait(false); } catch (Exception) { /* the loop reports its own end */ }
            }
            StopCommand = client.Submit(Command.JogStop());
            return await StopCommand.Reply.ConfigureAwait(false);
        }

        /// <summary>Release without waiting (for a button's up event); never throws.</summary>
        public void Release()
        {
            ReleaseAsync().ContinueWith(t => t.Exception, TaskContinuationOptions.ExecuteSynchronously);
        }

        public void Dispose()
        {
            if (Volatile.Read(ref released) == 0) Release();
        }
    }
}
