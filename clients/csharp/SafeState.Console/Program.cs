// SafeState.Console: a line-oriented client of the gateway, usable over SSH and in scripts.
//   mono SafeState.Console.exe --url ws://HOST:PORT/ws --role ROLE [--token-file F] [--live]
// Reads lines from stdin in the .scn spelling (spec/scenario-format.md) and prints each
// command's reply as one line `reply SEQ CMD RESULT` on stdout, in the order of the commands. Exits 0 at end of input
// once every command is answered; 1 when a command got no reply (timeout, lost link) or a
// `wait` timed out; 2 on a usage or connection error or a malformed line.
using System;
using System.Collections.Generic;
using System.Globalization;
using System.IO;
using System.Linq;
using System.Threading;
using System.Threading.Tasks;
using SafeState.Client;

namespace SafeState.ConsoleApp
{
    internal static class Program
    {
        private const string Usage =
            "usage: mono SafeState.Console.exe --url ws://HOST:PORT/ws --role pendant|remote|observer\n" +
            "       [--token-file FILE] [--live] [--timeout MS] [--client NAME]\n" +
            "The token comes from --token-file, else from SAFESTATE_PENDANT_TOKEN / SAFESTATE_REMOTE_TOKEN\n" +
            "(never from the command line). Lines on stdin (# starts a comment):\n" +
            "  reset | servo_on | servo_off | start | pause | resume | stop | jog AXIS +|- [SPEED] |\n" +
            "  jog_stop | confirm_t2 | set_mode MODE     a command (`cmd ` in front is allowed)\n" +
            "  in KEY=VALUE ...   fault WHAT              simulated cell only, loopback only\n" +
            "  hold AXIS +|- SPEED MS                     jog held for MS ms (keep-alive), then released\n" +
            "  wait KEY=VALUE ... [timeout=S]             until status has state=, sub=, mode= (default 10 s)\n" +
            "  sleep MS | status | alarms | history [AFTER_ID] | quit";

        private static int Main(string[] args)
        {
            Options o;
            string problem = Options.Parse(args, out o);
            if (problem != null)
            {
                Console.Error.WriteLine("SafeState.Console: " + problem);
                Console.Error.WriteLine(Usage);
                return 2;
            }
            int code;
            try
            {
                code = new Session(o).RunAsync(Console.In).GetAwaiter().GetResult();
            }
            catch (ConnectException e)
            {
                Console.Error.WriteLine("SafeState.Console: " + e.Message);
                code = 2;
            }
            return Exit(code);
        }

        // Mono 6.8 aborts the threads still in managed code when a process ends, and can fail
        // doing it ("Assertion at exception.c:109 ... ThreadAbortException", SIGABRT, exit 134:
        // mono/mono#20181): the thread-pool thread that completed the session is often one of
        // them. Everything is answered, printed and closed by now: under Mono the console ends
        // the process itself, with its exit code, once its output is flushed.
        [System.Runtime.InteropServices.DllImport("libc", EntryPoint = "_exit")]
        private static extern void NativeExit(int code);

        private static int Exit(int code)
        {
            Console.Out.Flush();
            Console.Error.Flush();
            if (Type.GetType("Mono.Runtime") != null && Environment.OSVersion.Platform == PlatformID.Unix)
            {
                NativeExit(code);
            }
            return code;
        }
    }

    internal sealed class Options
    {
        public Uri Url;
        public Role Role;
        public string Token;
        public bool Live;
        public int TimeoutMs = 5000;
        public string ClientName = "SafeState.Console";

        public static string Parse(string[] args, out Options o)
        {
            o = new Options();
            string roleName = null, tokenFile = null;
            for (int i = 0; i < args.Length; ++i)
            {
                string a = args[i];
                if (a == "--live") { o.Live = true; continue; }
                if (a == "--help" || a == "-h") return "help";
                if (i + 1 >= args.Length) return "unknown option or missing value: " + a;
                string v = args[++i];
                switch (a)
                {
                    case "--url":
                        Uri u;
                        if (!Uri.TryCreate(v, UriKind.Absolute, out u) || (u.Scheme != "ws" && u.Scheme != "wss")) return "--url needs ws://HOST:PORT/ws";
                        o.Url = u;
                        break;
                    case "--role": roleName = v; break;
                    case "--token-file": tokenFile = v; break;
                    case "--client": o.ClientName = v; break;
                    case "--timeout":
                        if (!int.TryParse(v, NumberStyles.None, CultureInfo.InvariantCulture, out o.TimeoutMs) || o.TimeoutMs < 1) return "--timeout needs milliseconds";
                        break;
                    case "--token":
                        return "--token is not accepted: a token on the command line is visible to every local user; use --token-file";
                    default: return "unknown option " + a;
                }
            }
            if (o.Url == null) return "--url is required";
            if (roleName == null || !Wire.TryParse(roleName, out o.Role)) return "--role must be pendant, remote or observer";
            return ReadToken(o, tokenFile);
        }

        private static string ReadToken(Options o, string tokenFile)
        {
            if (tokenFile != null)
            {
                try
                {
                    o.Token = File.ReadAllText(tokenFile).TrimEnd('\r', '\n');
                }
                catch (Exception e)
                {
                    return "cannot read --token-file: " + e.Message;
                }
                return null;
            }
            string env = o.Role == Role.pendant ? "SAFESTATE_PENDANT_TOKEN" : o.Role == Role.remote ? "SAFESTATE_REMOTE_TOKEN" : null;
            o.Token = env == null ? null : Environment.GetEnvironmentVariable(env);
            return null;
        }
    }

    internal sealed class Session
    {
        private readonly Options o;
        private readonly SafeStateClient client;
        private readonly object output = new object();
        private readonly List<Task> outstanding = new List<Task>();
        private Task printed = Task.FromResult(0);  // the last reply line in command order
        private readonly bool tty;
        private string lastLine = "";
        private int failures;
        private int malformed;

        public Session(Options o)
        {
            this.o = o;
            client = new SafeStateClient(new ClientOptions
            {
                ClientName = o.ClientName,
                CommandTimeout = TimeSpan.FromMilliseconds(o.TimeoutMs),
                UseSynchronizationContext = false,
            });
            tty = !Console.IsErrorRedirected;
        }

        public async Task<int> RunAsync(TextReader input)
        {
            client.Error += (s, e) => Note("error " + e);
            client.ConnectionChanged += (s, e) => Note("link " + e);
            if (o.Live)
            {
                client.Status += (s, st) => Live(st);
                client.Event += (s, ev) => Note("event " + ev.Line());
            }
            await client.ConnectAsync(o.Url, o.Role, o.Token).ConfigureAwait(false);
            Note("connected to " + client.Server + " as " + Wire.Name(o.Role));
            int lineNo = 0;
            string line;
            while ((line = await input.ReadLineAsync().ConfigureAwait(false)) != null)
            {
                ++lineNo;
                string text = Strip(line);
                if (text.Length == 0) continue;
                if (text == "quit") break;
                string problem = await Do(text).ConfigureAwait(false);
                if (problem != null)
                {
                    ++malformed;
                    Note("line " + lineNo + ": " + problem);
                }
            }
            await Barrier().ConfigureAwait(false);
            await client.CloseAsync().ConfigureAwait(false);
            return malformed > 0 ? 2 : failures > 0 ? 1 : 0;
        }

        private static string Strip(string line)
        {
            int hash = line.IndexOf('#');
            return (hash >= 0 ? line.Substring(0, hash) : line).Trim();
        }

        private async Task<string> Do(string text)
        {
            string[] w = text.Split(new[] { ' ', '\t' }, StringSplitOptions.RemoveEmptyEntries);
            switch (w[0])
            {
                case "cmd": return Send(string.Join(" ", w.Skip(1)));
                case "in": return SimSet(w);
                case "fault":
                    Track("fault", client.SubmitSim(null, string.Join(" ", w.Skip(1))));
                    return null;
                case "wait": return await Wait(w).ConfigureAwait(false);
                case "sleep":
                    int ms;
                    if (w.Length != 2 || !int.TryParse(w[1], NumberStyles.None, CultureInfo.InvariantCulture, out ms)) return "sleep takes milliseconds";
                    await Barrier().ConfigureAwait(false);
                    await Task.Delay(ms).ConfigureAwait(false);
                    return null;
                case "hold": return await Hold(w).ConfigureAwait(false);
                case "status":
                    await Barrier().ConfigureAwait(false);
                    Print(client.LastStatus == null ? "status none" : "status " + client.LastStatus.Line());
                    return null;
                case "alarms": return await Alarms().ConfigureAwait(false);
                case "history": return await History(w).ConfigureAwait(false);
                default: return Send(text);
            }
        }

        private string Send(string text)
        {
            Command c;
            string error;
            if (!Command.TryParse(text, out c, out error)) return error;
            Track(Wire.Name(c.Name), client.Submit(c));
            return null;
        }

        private string SimSet(string[] w)
        {
            if (w.Length < 2) return "in takes KEY=VALUE ...";
            var set = new JsonObject();
            foreach (string kv in w.Skip(1))
            {
                int eq = kv.IndexOf('=');
                if (eq <= 0) return "in takes KEY=VALUE, not \"" + kv + "\"";
                string value = kv.Substring(eq + 1);
                long n;
                // Raw channels take 0/1 as numbers, shorthands take words (protocol.md `sim`).
                if (long.TryParse(value, NumberStyles.None, CultureInfo.InvariantCulture, out n)) set.Set(kv.Substring(0, eq), n);
                else set.Set(kv.Substring(0, eq), value);
            }
            Track("in", client.SubmitSim(set));
            return null;
        }

        // Prints the reply line when it comes, in the order the commands were given: the client
        // completes replies on the thread pool (RunContinuationsAsynchronously), so two replies in
        // one frame could otherwise print in either order and a script's output would vary.
        // A command without reply counts as a failure.
        private void Track(string name, PendingCommand command)
        {
            Task t;
            lock (outstanding)
            {
                t = PrintInOrder(printed, name, command);
                printed = t;
                outstanding.Add(t);
            }
        }

        private async Task PrintInOrder(Task previous, string name, PendingCommand command)
        {
            Result result = default(Result);
            Exception error = null;
            try { result = await command.Reply.ConfigureAwait(false); }
            catch (Exception e) { error = e; }
            await previous.ConfigureAwait(false);  // never faults: every link of the chain catches
            if (error == null)
            {
                Print("reply " + command.Seq + " " + name + " " + Wire.Name(result));
                return;
            }
            Interlocked.Increment(ref failures);
            Exception inner = error is AggregateException && error.InnerException != null ? error.InnerException : error;
            Print("noreply " + name + " " + (inner is TaskCanceledException ? "cancelled" : inner.Message));
        }

        private async Task Barrier()
        {
            Task[] all;
            lock (outstanding)
            {
                all = outstanding.ToArray();
                outstanding.Clear();
            }
            await Task.WhenAll(all).ConfigureAwait(false);
        }

        private async Task<string> Wait(string[] w)
        {
            var want = new Dictionary<string, string>();
            double seconds = 10;
            foreach (string kv in w.Skip(1))
            {
                int eq = kv.IndexOf('=');
                if (eq <= 0) return "wait takes KEY=VALUE ...";
                string k = kv.Substring(0, eq), v = kv.Substring(eq + 1);
                if (k == "timeout")
                {
                    if (!double.TryParse(v, NumberStyles.Float, CultureInfo.InvariantCulture, out seconds) || seconds <= 0) return "timeout=S needs seconds";
                    continue;
                }
                if (k != "state" && k != "sub" && k != "mode") return "wait knows state=, sub=, mode=, timeout=";
                want[k] = v;
            }
            if (want.Count == 0) return "wait needs state=, sub= or mode=";
            await Barrier().ConfigureAwait(false);
            var deadline = DateTime.UtcNow.AddSeconds(seconds);
            while (DateTime.UtcNow < deadline)
            {
                StatusMessage s = client.LastStatus;
                if (s != null && Matches(s, want))
                {
                    Print("wait ok " + s.Line());
                    return null;
                }
                await Task.Delay(10).ConfigureAwait(false);
            }
            Interlocked.Increment(ref failures);
            Print("wait timeout " + string.Join(" ", w.Skip(1)) + "; last " + (client.LastStatus == null ? "none" : client.LastStatus.Line()));
            return null;
        }

        private static bool Matches(StatusMessage s, Dictionary<string, string> want)
        {
            string v;
            if (want.TryGetValue("state", out v) && Wire.Name(s.State) != v) return false;
            if (want.TryGetValue("sub", out v) && (s.Sub.HasValue ? Wire.Name(s.Sub.Value) : "-") != v) return false;
            if (want.TryGetValue("mode", out v) && Wire.Name(s.Mode) != v) return false;
            return true;
        }

        private async Task<string> Hold(string[] w)
        {
            int axis, speed, ms;
            if (w.Length != 5 || !int.TryParse(w[1], out axis) || axis < 1 || axis > 6 || (w[2] != "+" && w[2] != "-") ||
                !int.TryParse(w[3], out speed) || speed < 1 || speed > 100 || !int.TryParse(w[4], out ms) || ms < 0)
            {
                return "hold takes AXIS +|- SPEED MS";
            }
            await Barrier().ConfigureAwait(false);
            JogHold h = client.HoldJog(axis, w[2][0], speed);
            Track("jog", h.FirstCommand);
            await Task.Delay(ms).ConfigureAwait(false);
            bool stillActive = h.Active;
            try
            {
                await h.ReleaseAsync().ConfigureAwait(false);
            }
            catch (Exception)
            {
                // Reported below through the jog_stop's own line.
            }
            Track("jog_stop", h.StopCommand);
            await Barrier().ConfigureAwait(false);
            Print("hold " + (stillActive ? "released" : "ended early: " + h.EndReason) + " after " + h.Sent + " jog commands");
            return null;
        }

        private async Task<string> Alarms()
        {
            await Barrier().ConfigureAwait(false);
            using (var h = new HistoryClient(HistoryClient.BaseOf(o.Url), o.Token))
            {
                try
                {
                    IReadOnlyList<AlarmEntry> list = await h.GetAlarmsAsync().ConfigureAwait(false);
                    Print("alarms " + list.Count);
                    foreach (AlarmEntry a in list) Print("alarm " + a.Line());
                }
                catch (Exception e)
                {
                    Interlocked.Increment(ref failures);
                    Print("alarms failed: " + e.Message);
                }
            }
            return null;
        }

        private async Task<string> History(string[] w)
        {
            long after = 0;
            if (w.Length > 2 || (w.Length == 2 && (!long.TryParse(w[1], NumberStyles.None, CultureInfo.InvariantCulture, out after))))
            {
                return "history takes an optional event id to start after";
            }
            await Barrier().ConfigureAwait(false);
            using (var h = new HistoryClient(HistoryClient.BaseOf(o.Url), o.Token))
            {
                try
                {
                    EventPager pager = h.Events(after, HistoryClient.MaxPage);
                    int n = 0;
                    for (IReadOnlyList<EventMessage> page; (page = await pager.NextAsync().ConfigureAwait(false)).Count > 0;)
                    {
                        foreach (EventMessage e in page) Print("history " + e.Line());
                        n += page.Count;
                    }
                    Print("history " + n + " events, last id " + pager.After);
                }
                catch (Exception e)
                {
                    Interlocked.Increment(ref failures);
                    Print("history failed: " + e.Message);
                }
            }
            return null;
        }

        private void Print(string line)
        {
            lock (output)
            {
                ClearLive();
                Console.Out.WriteLine(line);
                Console.Out.Flush();
            }
        }

        private void Note(string line)
        {
            lock (output)
            {
                ClearLive();
                Console.Error.WriteLine(line);
            }
        }

        // The live status line: redrawn in place on a terminal, one line per change otherwise.
        private void Live(StatusMessage s)
        {
            string line = Wire.Name(s.State) + (s.Sub.HasValue ? "/" + Wire.Name(s.Sub.Value) : "") + " mode=" + Wire.Name(s.Mode) +
                          " stop=" + (s.Stop.HasValue ? Wire.Name(s.Stop.Value) : "-") + " alarms=" +
                          (s.Alarms.Count == 0 ? "-" : string.Join(",", s.Alarms));
            lock (output)
            {
                if (line == lastLine) return;
                lastLine = line;
                if (tty) Console.Error.Write("\r\x1b[K" + s.Line());
                else Console.Error.WriteLine("status " + s.Line());
            }
        }

        private void ClearLive()
        {
            if (tty && lastLine.Length > 0)
            {
                Console.Error.Write("\r\x1b[K");
                lastLine = "";
            }
        }
    }
}
