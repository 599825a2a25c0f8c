// The WebSocket client of protocol.md. One receive loop per connection reads frames, checks
// them strictly (Messages.cs) and raises events; nothing read from the server is ever
// thrown at the caller: bad input becomes an Error event. Every SendAsync completes with
// exactly the reply to its seq, or fails with CommandFailedException on timeout, lost link
// or close; it never hangs. After a lost link the client reconnects with back-off but
// never re-sends a command (a motion command re-sent later would be an unexpected
// start-up, ISO 10218-1 5.4.3 / ISO 12100 6.2.11.4): pending commands fail, jog holds stop.
using System;
using System.Collections.Generic;
using System.IO;
using System.Linq;
using System.Net.WebSockets;
using System.Text;
using System.Threading;
using System.Threading.Tasks;

namespace SafeState.Client
{
    public enum ConnectionState
    {
        Disconnected,
        Connecting,
        Connected,
        Reconnecting,
        Closed,
    }

    public sealed class ClientOptions
    {
        public ClientOptions()
        {
            CommandTimeout = TimeSpan.FromSeconds(5);
            ConnectTimeout = TimeSpan.FromSeconds(5);
            AutoReconnect = true;
            FirstReconnectDelay = TimeSpan.FromMilliseconds(100);
            MaxReconnectDelay = TimeSpan.FromSeconds(5);
            MaxFrameBytes = 64 * 1024;
            JogKeepAlive = TimeSpan.FromMilliseconds(40);
            ClientName = "SafeState.Client";
            UseSynchronizationContext = true;
            MaxErrorsPerSecond = 20;
        }

        /// <summary>A command without a reply after this fails with CommandFailure.Timeout.</summary>
        public TimeSpan CommandTimeout { get; set; }
        public TimeSpan ConnectTimeout { get; set; }
        public bool AutoReconnect { get; set; }
        public TimeSpan FirstReconnectDelay { get; set; }
        public TimeSpan MaxReconnectDelay { get; set; }
        /// <summary>A larger frame is discarded and reported (status is about 1.5 KiB).</summary>
        public int MaxFrameBytes { get; set; }
        /// <summary>Jog repeat period while held; well inside jog_timeout_ms (100 ms, SPEC rule 7).</summary>
        public TimeSpan JogKeepAlive { get; set; }
        public string ClientName { get; set; }
        /// <summary>Raise events on the SynchronizationContext of the constructing thread (a UI thread).</summary>
        public bool UseSynchronizationContext { get; set; }
        /// <summary>Error events of one kind per second; beyond it they are counted, and the count is
        /// reported with the next one, so a server flooding bad frames cannot flood the UI thread.</summary>
        public int MaxErrorsPerSecond { get; set; }
    }

    /// <summary>A command on its way: the seq it was sent with (0: not sent) and its reply.</summary>
    public sealed class PendingCommand
    {
        public PendingCommand(long seq, Task<Result> reply)
        {
            Seq = seq;
            Reply = reply;
        }

        public long Seq { get; private set; }
        public Task<Result> Reply { get; private set; }
    }

    /// <summary>ConnectAsync failed: the server refused the hello, or could not be reached.</summary>
    public sealed class ConnectException : Exception
    {
        public ConnectException(string message, string serverCode = null, Exception inner = null) : base(message, inner)
        {
            ServerCode = serverCode;
        }

        public string ServerCode { get; private set; }
    }

    public sealed class SafeStateClient : IDisposable
    {
        private static readonly Encoding StrictUtf8 = new UTF8Encoding(false, true);

        private readonly ClientOptions options;
        private readonly SynchronizationContext context;
        private readonly object gate = new object();
        private readonly Dictionary<long, Pending> pending = new Dictionary<long, Pending>();
        private readonly List<JogHold> jogs = new List<JogHold>();
        private readonly CancellationTokenSource life = new CancellationTokenSource();
        private Connection current;
        private Uri uri;
        private Role role;
        private string token;
        private long nextSeq;
        private ConnectionState state = ConnectionState.Disconnected;

        public SafeStateClient(ClientOptions options = null)
        {
            this.options = options ?? new ClientOptions();
            context = this.options.UseSynchronizationContext ? SynchronizationContext.Current : null;
        }

        /// <summary>Each status message (50 Hz).</summary>
        public event EventHandler<StatusMessage> Status;
        /// <summary>Each event: transition, alarm, alarm_cleared, command.</summary>
        public event EventHandler<EventMessage> Event;
        /// <summary>Bad server input, server errors, lost links: never thrown at the caller.</summary>
        public event EventHandler<ClientError> Error;
        public event EventHandler<ConnectionState> ConnectionChanged;

        public ClientOptions Options { get { return options; } }
        public ConnectionState State { get { return state; } }
        public StatusMessage LastStatus { get; private set; }
        /// <summary>The server's name and version from its welcome.</summary>
        public string Server { get; private set; }
        public Role Role { get { return role; } }
        /// <summary>How many times the link was re-established after a loss.</summary>
        public int Reconnects { get; private set; }
        /// <summary>Messages sent, counted by the client (commands and sims), for tests and diagnostics.</summary>
        public long Sent { get { return Interlocked.Read(ref sent); } }
        private long sent;

        // ------------------------------------------------------------------ connecting
        public async Task ConnectAsync(Uri uri, Role role, string token = null, CancellationToken cancel = default(CancellationToken))
        {
            if (uri == null) throw new ArgumentNullException("uri");
            if (uri.Scheme != "ws" && uri.Scheme != "wss") throw new ArgumentException("the URL must be ws:// or wss://", "uri");
            lock (gate)
            {
                if (state == ConnectionState.Closed) throw new ObjectDisposedException("SafeStateClient");
                if (state != ConnectionState.Disconnected) throw new InvalidOperationException("already " + state);
                this.uri = uri;
                this.role = role;
                this.token = token;
            }
            SetState(ConnectionState.Connecting);
            try
            {
                await OpenAsync(cancel).ConfigureAwait(false);
            }
            catch
            {
                SetState(ConnectionState.Disconnected);
                throw;
            }
        }

        private async Task OpenAsync(CancellationToken cancel)
        {
            var ws = new ClientWebSocket();
            var c = new Connection(ws);
            using (var cts = CancellationTokenSource.CreateLinkedTokenSource(cancel, life.Token))
            {
                cts.CancelAfter(options.ConnectTimeout);
                try
                {
                    await ws.ConnectAsync(uri, cts.Token).ConfigureAwait(false);
                }
                catch (Exception e)
                {
                    ws.Dispose();
                    throw new ConnectException("cannot connect to " + uri + ": " + Describe(e), null, e);
                }
                c.Receiver = Task.Run(() => ReceiveLoop(c));
                var hello = new JsonObject().Set("type", "hello").Set("role", Wire.Name(role)).Set("client", options.ClientName);
                if (!string.IsNullOrEmpty(token)) hello.Set("token", token);
                JsonObject answer;
                try
                {
                    await SendText(c, Json.Write(hello), cts.Token).ConfigureAwait(false);
                    using (cts.Token.Register(() => c.Hello.TrySetCanceled()))
                    {
                        answer = await c.Hello.Task.ConfigureAwait(false);
                    }
                }
                catch (Exception e)
                {
                    c.Abort();
                    throw new ConnectException("no welcome from " + uri + ": " + Describe(e), null, e);
                }
                if ((answer["type"] as string) == "error")
                {
                    c.Abort();
                    throw new ConnectException("hello refused: " + answer["code"] + " " + answer["detail"], answer["code"] as string);
                }
                Server = answer["server"] as string;
                lock (gate)
                {
                    if (life.IsCancellationRequested)
                    {
                        c.Abort();
                        throw new ObjectDisposedException("SafeStateClient");
                    }
                    if (c.Ended)
                    {
                        // Lost between the welcome and here: its end was not treated as a loss.
                        throw new ConnectException("the link closed right after the welcome from " + uri);
                    }
                    c.Established = true;
                    current = c;
                }
                SetState(ConnectionState.Connected);
            }
        }

        private static string Describe(Exception e)
        {
            var agg = e as AggregateException;
            if (agg != null && agg.InnerException != null) e = agg.InnerException;
            if (e is OperationCanceledException) return "timed out";
            return e.InnerException != null ? e.Message + " (" + e.InnerException.Message + ")" : e.Message;
        }

        // ------------------------------------------------------------------ commands
        /// <summary>Sends one command; completes with exactly the reply to its seq.</summary>
        public Task<Result> SendAsync(Command command)
        {
            return Submit(command).Reply;
        }

        /// <summary>As SendAsync, and also tells the seq the command was sent with.</summary>
        public PendingCommand Submit(Command command)
        {
            if (command == null) throw new ArgumentNullException("command");
            return Request(seq => command.ToMessage(seq), command.ToString(), false);
        }

        /// <summary>Simulated cell only, loopback only: sets inputs in the .scn vocabulary
        /// (e.g. {"mode":"T1"}) or injects a fault ("drive 3 fault"). Completes with the reply;
        /// a server `error` (NOT_SIMULATED, BAD_MESSAGE) fails it with CommandFailure.Refused.</summary>
        public Task<Result> SimAsync(JsonObject set, string fault = null)
        {
            return SubmitSim(set, fault).Reply;
        }

        public PendingCommand SubmitSim(JsonObject set, string fault = null)
        {
            return Request(seq =>
            {
                var o = new JsonObject().Set("type", "sim").Set("seq", seq);
                if (set != null) o.Set("set", set);
                if (fault != null) o.Set("fault", fault);
                return o;
            }, "sim", true);
        }

        private PendingCommand Request(Func<long, JsonObject> build, string what, bool isSim)
        {
            Connection c;
            lock (gate) c = current;
            if (c == null)
            {
                return new PendingCommand(0, Failed(CommandFailure.NotConnected, what + ": not connected (" + state + ")"));
            }
            long seq = Interlocked.Increment(ref nextSeq);
            var p = new Pending(what, isSim);
            p.Timer = new CancellationTokenSource();
            p.Timer.Token.Register(() => Fail(seq, CommandFailure.Timeout,
                what + " (seq " + seq + "): no reply within " + options.CommandTimeout.TotalMilliseconds + " ms"));
            bool stale;
            lock (gate)
            {
                pending[seq] = p;
                stale = current != c;  // lost between the two locks: FailAll may already have run
            }
            if (stale)
            {
                Fail(seq, CommandFailure.Disconnected, what + ": the link was lost before it could be sent; not re-sent");
                return new PendingCommand(seq, p.Tcs.Task);
            }
            try
            {
                p.Timer.CancelAfter(options.CommandTimeout);
            }
            catch (ObjectDisposedException)
            {
                return new PendingCommand(seq, p.Tcs.Task);  // already failed by a lost link
            }
            string text = Json.Write(build(seq));
            Interlocked.Increment(ref sent);
            SendWithTimeout(c, text).ContinueWith(t =>
            {
                if (t.IsFaulted || t.IsCanceled)
                {
                    Fail(seq, CommandFailure.Disconnected, what + " (seq " + seq + "): could not be sent: " +
                        (t.Exception != null ? Describe(t.Exception) : "cancelled"));
                }
            }, TaskContinuationOptions.ExecuteSynchronously);
            return new PendingCommand(seq, p.Tcs.Task);
        }

        private static Task<Result> Failed(CommandFailure reason, string message)
        {
            var tcs = new TaskCompletionSource<Result>(TaskCreationOptions.RunContinuationsAsynchronously);
            tcs.SetException(new CommandFailedException(reason, message));
            return tcs.Task;
        }

        private Pending Take(long seq)
        {
            Pending p;
            lock (gate)
            {
                if (!pending.TryGetValue(seq, out p)) return null;
                pending.Remove(seq);
            }
            p.Timer.Dispose();
            return p;
        }

        private void Fail(long seq, CommandFailure reason, string message)
        {
            Pending p = Take(seq);
            if (p != null) p.Tcs.TrySetException(new CommandFailedException(reason, message));
        }

        private void FailAll(CommandFailure reason, string why)
        {
            List<long> seqs;
            lock (gate) seqs = pending.Keys.ToList();
            foreach (long s in seqs) Fail(s, reason, "seq " + s + ": " + why);
        }

        private async Task SendWithTimeout(Connection c, string text)
        {
            // Its own token: the pending command's timer is disposed when the reply comes,
            // which may be before the send has returned.
            using (var cts = new CancellationTokenSource(options.CommandTimeout))
            {
                await SendText(c, text, cts.Token).ConfigureAwait(false);
            }
        }

        private async Task SendText(Connection c, string text, CancellationToken cancel)
        {
            byte[] bytes = Encoding.UTF8.GetBytes(text);
            // ClientWebSocket allows one send at a time; the keep-alive and the UI share the link.
            await c.SendLock.WaitAsync(cancel).ConfigureAwait(false);
            try
            {
                await c.Ws.SendAsync(new ArraySegment<byte>(bytes), WebSocketMessageType.Text, true, cancel).ConfigureAwait(false);
            }
            finally
            {
                c.SendLock.Release();
            }
        }

        // ------------------------------------------------------------------ jog
        /// <summary>Starts jogging while a button is held: repeats `jog` every JogKeepAlive
        /// until Release (then `jog_stop`). It stops by itself, and is never resumed, when a
        /// keep-alive is refused or the link is lost.</summary>
        public JogHold HoldJog(int axis, char dir, int speed = 10)
        {
            var hold = new JogHold(this, Command.Jog(axis, dir, speed), options.JogKeepAlive);
            lock (gate) jogs.Add(hold);
            hold.Begin();
            return hold;
        }

        internal void Forget(JogHold hold)
        {
            lock (gate) jogs.Remove(hold);
        }

        private void StopJogs(string why)
        {
            List<JogHold> list;
            lock (gate) list = jogs.ToList();
            foreach (JogHold j in list) j.LinkLost(why);
        }

        // ------------------------------------------------------------------ receiving
        private async Task ReceiveLoop(Connection c)
        {
            var buffer = new byte[8192];
            var frame = new MemoryStream();
            string reason = "closed by the server";
            try
            {
                while (true)
                {
                    frame.SetLength(0);
                    bool tooLarge = false;
                    WebSocketReceiveResult r;
                    do
                    {
                        r = await c.Ws.ReceiveAsync(new ArraySegment<byte>(buffer), CancellationToken.None).ConfigureAwait(false);
                        if (r.MessageType == WebSocketMessageType.Close) break;
                        tooLarge = tooLarge || frame.Length + r.Count > options.MaxFrameBytes;
                        if (!tooLarge) frame.Write(buffer, 0, r.Count);
                    } while (!r.EndOfMessage);
                    if (r.MessageType == WebSocketMessageType.Close)
                    {
                        reason = "closed by the server (" + r.CloseStatus + " " + r.CloseStatusDescription + ")";
                        break;
                    }
                    OnFrame(c, r.MessageType, frame, tooLarge);
                }
            }
            catch (Exception e)
            {
                reason = Describe(e);
            }
            OnConnectionEnded(c, reason);
        }

        private void OnFrame(Connection c, WebSocketMessageType type, MemoryStream frame, bool tooLarge)
        {
            if (tooLarge)
            {
                Report(ClientErrorKind.TooLarge, "a frame over " + options.MaxFrameBytes + " bytes was discarded");
                return;
            }
            if (type == WebSocketMessageType.Binary)
            {
                Report(ClientErrorKind.BinaryFrame, "a binary frame (" + frame.Length + " bytes) was discarded");
                return;
            }
            string text;
            try
            {
                text = StrictUtf8.GetString(frame.GetBuffer(), 0, (int)frame.Length);
            }
            catch (ArgumentException)
            {
                Report(ClientErrorKind.BadJson, "a text frame that is not valid UTF-8 was discarded");
                return;
            }
            try
            {
                Handle(c, text);
            }
            catch (Exception e)
            {
                // Nothing read from the network may end the loop or reach the caller.
                Report(ClientErrorKind.BadMessage, "a message could not be handled: " + e.Message + " in " + Excerpt(text));
            }
        }

        private static string Excerpt(string text)
        {
            return text.Length <= 120 ? text : text.Substring(0, 120) + "...";
        }

        private void Handle(Connection c, string text)
        {
            object value;
            try
            {
                value = Json.Parse(text);
            }
            catch (JsonException e)
            {
                Report(ClientErrorKind.BadJson, e.Message + " in " + Excerpt(text));
                return;
            }
            Fields f;
            string type;
            try
            {
                f = new Fields(value, "message");
                type = f.Str("type");
            }
            catch (MessageException e)
            {
                Report(ClientErrorKind.BadMessage, e.Message + " in " + Excerpt(text));
                return;
            }
            var unknownNames = new List<string>();
            try
            {
                Dispatch(c, type, f, unknownNames);
            }
            catch (MessageException e)
            {
                Report(ClientErrorKind.BadMessage, type + ": " + e.Message + " in " + Excerpt(text));
                return;
            }
            foreach (string k in f.Unknown()) unknownNames.Add("field " + type + "." + k);
            foreach (string n in unknownNames)
            {
                if (c.ReportedUnknown.Add(n)) Report(ClientErrorKind.UnknownField, "unknown " + n + " (reported once per connection)");
            }
        }

        private void Dispatch(Connection c, string type, Fields f, List<string> unknownNames)
        {
            switch (type)
            {
                case "welcome":
                    f.Name<Role>("role");
                    f.Str("server");
                    if (!c.Hello.TrySetResult(f.Object)) Report(ClientErrorKind.BadMessage, "a welcome nobody asked for");
                    return;
                case "error":
                    OnServerError(c, f);
                    return;
                case "reply":
                    OnReply(f);
                    return;
                case "status":
                {
                    StatusMessage s = StatusMessage.Read(f, unknownNames);
                    LastStatus = s;
                    Raise(Status, s);
                    return;
                }
                case "event":
                    Raise(Event, EventMessage.Read(f, false));
                    return;
                default:
                    throw new MessageException("unknown message type \"" + type + "\"");
            }
        }

        private void OnServerError(Connection c, Fields f)
        {
            string code = f.Str("code");
            string detail = f.StrOrNull("detail", true) ?? "";
            ErrorCode known;
            if (!Wire.TryParse(code, out known)) throw f.Bad("code", "a protocol.md error code, not \"" + code + "\"");
            if (c.Hello.TrySetResult(f.Object)) return;  // the answer to our hello: ConnectAsync fails with it
            // A sim that was refused is answered by an error without seq: the oldest pending sim.
            long sim = -1;
            lock (gate)
            {
                foreach (KeyValuePair<long, Pending> p in pending)
                {
                    if (p.Value.IsSim && (sim < 0 || p.Key < sim)) sim = p.Key;
                }
            }
            if (sim >= 0 && (known == ErrorCode.BAD_MESSAGE || known == ErrorCode.NOT_SIMULATED))
            {
                Fail(sim, CommandFailure.Refused, "sim refused: " + code + " " + detail);
                return;
            }
            Report(ClientErrorKind.ServerError, detail, code);
        }

        private void OnReply(Fields f)
        {
            long seq = f.Int("seq");
            string name = f.Str("result");
            Result result;
            if (!Wire.TryParse(name, out result))
            {
                Fail(seq, CommandFailure.BadReply, "seq " + seq + ": unknown result \"" + name + "\"");
                throw f.Bad("result", "a SPEC.md result name, not \"" + name + "\"");
            }
            Pending p = Take(seq);
            if (p == null)
            {
                Report(ClientErrorKind.UnexpectedReply, "reply to seq " + seq + " (" + name + ") that no pending command has");
                return;
            }
            p.Tcs.TrySetResult(result);
        }

        private void OnConnectionEnded(Connection c, string reason)
        {
            c.Hello.TrySetException(new IOException(reason));
            bool reconnect;
            lock (gate)
            {
                c.Ended = true;
                if (!c.Established || current != c) return;  // a failed attempt, or closed by us
                current = null;
                reconnect = options.AutoReconnect && !life.IsCancellationRequested;
            }
            c.Abort();
            FailAll(CommandFailure.Disconnected, "the link was lost before the reply (" + reason + "); not re-sent");
            StopJogs("the link was lost");
            Report(ClientErrorKind.Disconnected, reason);
            SetState(reconnect ? ConnectionState.Reconnecting : ConnectionState.Disconnected);
            if (reconnect) Task.Run(() => ReconnectLoop());
        }

        // Jittered exponential back-off (Backoff): after a gateway restart, or refused in a
        // burst (503 / close 1013), the clients of a plant do not all return at once.
        private async Task ReconnectLoop()
        {
            var random = new Random(Guid.NewGuid().GetHashCode());
            int failures = 1;  // the link that was lost
            TimeSpan delay = Backoff.Delay(failures, options.FirstReconnectDelay, options.MaxReconnectDelay, random.NextDouble());
            while (!life.IsCancellationRequested)
            {
                try
                {
                    await Task.Delay(delay, life.Token).ConfigureAwait(false);
                    await OpenAsync(CancellationToken.None).ConfigureAwait(false);
                    Reconnects++;
                    return;
                }
                catch (Exception e)
                {
                    if (life.IsCancellationRequested) return;
                    failures = Math.Min(failures + 1, 62);
                    delay = Backoff.Delay(failures, options.FirstReconnectDelay, options.MaxReconnectDelay, random.NextDouble());
                    Report(ClientErrorKind.ReconnectFailed, Describe(e) + "; next attempt in " + (long)delay.TotalMilliseconds + " ms");
                }
            }
        }

        // ------------------------------------------------------------------ events
        private void SetState(ConnectionState s)
        {
            lock (gate)
            {
                if (state == s || state == ConnectionState.Closed) return;
                state = s;
            }
            Raise(ConnectionChanged, s);
        }

        internal void Report(ClientErrorKind kind, string message, string code = null)
        {
            long now = Environment.TickCount & int.MaxValue;
            int suppressed = 0;
            bool emit;
            lock (gate)
            {
                ErrorWindow w;
                if (!errorWindows.TryGetValue(kind, out w)) errorWindows[kind] = w = new ErrorWindow { Start = now };
                if (now - w.Start >= 1000 || now < w.Start)
                {
                    suppressed = w.Suppressed;
                    w.Start = now;
                    w.Count = 0;
                    w.Suppressed = 0;
                }
                emit = ++w.Count <= options.MaxErrorsPerSecond;
                if (!emit && ++w.Suppressed == 1) ScheduleFlush(kind, w.Start, 1000 - (now - w.Start));
            }
            if (suppressed > 0)
            {
                RaiseSuppressed(kind, suppressed);
            }
            if (emit) Raise(Error, new ClientError(kind, message, code));
        }

        // The count of a window's suppressed errors is raised when the window ends, not only when
        // a later error of that kind happens to come: a flood that stops must still be accounted
        // for in full (every error raised or counted).
        private void ScheduleFlush(ClientErrorKind kind, long windowStart, long delayMs)
        {
            Task.Delay(TimeSpan.FromMilliseconds(Math.Max(1, delayMs)), life.Token).ContinueWith(t =>
            {
                if (t.IsCanceled) return;
                int suppressed = 0;
                lock (gate)
                {
                    ErrorWindow w;
                    if (errorWindows.TryGetValue(kind, out w) && w.Start == windowStart)
                    {
                        suppressed = w.Suppressed;
                        w.Suppressed = 0;
                    }
                }
                if (suppressed > 0)
                {
                    RaiseSuppressed(kind, suppressed);
                }
            }, TaskScheduler.Default);
        }

        private void RaiseSuppressed(ClientErrorKind kind, int suppressed)
        {
            Raise(Error, new ClientError(kind, suppressed + " more " + kind + " errors were not raised (over " +
                                               options.MaxErrorsPerSecond + " a second)"));
        }

        private sealed class ErrorWindow
        {
            public long Start;
            public int Count;
            public int Suppressed;
        }

        private readonly Dictionary<ClientErrorKind, ErrorWindow> errorWindows = new Dictionary<ClientErrorKind, ErrorWindow>();

        private void Raise<T>(EventHandler<T> handler, T arg)
        {
            if (handler == null) return;
            SendOrPostCallback call = _ =>
            {
                try
                {
                    handler(this, arg);
                }
                catch (Exception e)
                {
                    // An application handler that throws must not stop the receive loop.
                    if (!ReferenceEquals(handler, Error)) Report(ClientErrorKind.HandlerFailed, e.GetType().Name + ": " + e.Message);
                }
            };
            if (context != null) context.Post(call, null);
            else call(null);
        }

        // ------------------------------------------------------------------ closing
        /// <summary>Closes the link; pending commands fail with CommandFailure.Closed.</summary>
        public async Task CloseAsync()
        {
            Connection c;
            lock (gate)
            {
                if (state == ConnectionState.Closed) return;
                life.Cancel();
                c = current;
                current = null;
            }
            FailAll(CommandFailure.Closed, "the client was closed");
            StopJogs("the client was closed");
            if (c != null)
            {
                try
                {
                    using (var t = new CancellationTokenSource(TimeSpan.FromSeconds(1)))
                    {
                        await c.Ws.CloseOutputAsync(WebSocketCloseStatus.NormalClosure, "bye", t.Token).ConfigureAwait(false);
                    }
                }
                catch (Exception)
                {
                    // Mono may throw here when the server is already gone: the socket is aborted anyway.
                }
                c.Abort();
            }
            SetState(ConnectionState.Closed);
        }

        public void Dispose()
        {
            CloseAsync().Wait(TimeSpan.FromSeconds(2));
        }

        private sealed class Pending
        {
            public Pending(string what, bool isSim)
            {
                What = what;
                IsSim = isSim;
                Tcs = new TaskCompletionSource<Result>(TaskCreationOptions.RunContinuationsAsynchronously);
            }

            public readonly string What;
            public readonly bool IsSim;
            public readonly TaskCompletionSource<Result> Tcs;
            public CancellationTokenSource Timer;
        }

        private sealed class Connection
        {
            public Connection(ClientWebSocket ws)
            {
                Ws = ws;
                Hello = new TaskCompletionSource<JsonObject>(TaskCreationOptions.RunContinuationsAsynchronously);
            }

            public readonly ClientWebSocket Ws;
            public readonly SemaphoreSlim SendLock = new SemaphoreSlim(1, 1);
            public readonly TaskCompletionSource<JsonObject> Hello;
            public readonly HashSet<string> ReportedUnknown = new HashSet<string>();
            public Task Receiver;
            public bool Established;  // both under the client's gate
            public bool Ended;

            public void Abort()
            {
                try
                {
                    Ws.Abort();
                    Ws.Dispose();
                }
                catch (Exception)
                {
                    // Already aborted or disposed.
                }
            }
        }
    }
}
