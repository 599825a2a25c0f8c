// One real `safestate run` on the simulated cell on a free loopback port, as the Python
// protocol tests start it (tests/integration/test_gateway.py), plus waiting helpers. Every
// wait polls with a timeout of seconds: the VM may stall for tens of milliseconds.
using System;
using System.Collections.Generic;
using System.Diagnostics;
using System.IO;
using System.Net;
using System.Net.Sockets;
using System.Text;
using System.Threading;
using System.Threading.Tasks;
using NUnit.Framework;
using SafeState.Client;

namespace SafeState.Tests
{
    internal sealed class Cell : IDisposable
    {
        public const double StartupSeconds = 20;
        private readonly Process proc;
        private readonly StringBuilder log = new StringBuilder();
        private readonly string dir;

        public Cell() : this("", null)
        {
        }

        /// <param name="args">extra options of `safestate run`</param>
        /// <param name="env">extra environment (e.g. SAFESTATE_PENDANT_TOKEN)</param>
        public Cell(string args, IDictionary<string, string> env)
        {
            Port = FreePort();
            dir = Path.Combine(Path.GetTempPath(), "safestate-cs-" + Port + "-" + Guid.NewGuid().ToString("N").Substring(0, 8));
            Directory.CreateDirectory(dir);
            var psi = new ProcessStartInfo(Bin)
            {
                Arguments = "run --port " + Port + " --db " + Path.Combine(dir, "events.db") + " --cycle-us 1000 " +
                            // default: SPEC §14's cross-check window widened (tests/integration/test_gateway.py
                            // STALL_TOLERANT_PAIR: these tests check the client, not the pair's timing)
                            (Environment.GetEnvironmentVariable("SAFESTATE_RUN_ARGS") ?? "--cross-check-cycles 50") + " " + args,
                UseShellExecute = false,
                RedirectStandardOutput = true,
                RedirectStandardError = true,
                WorkingDirectory = dir,
            };
            // These tests do not depend on token enforcement: a pendant without a token is
            // accepted on loopback when the server has none (protocol.md).
            psi.EnvironmentVariables.Remove("SAFESTATE_PENDANT_TOKEN");
            psi.EnvironmentVariables.Remove("SAFESTATE_REMOTE_TOKEN");
            if (env != null)
            {
                foreach (KeyValuePair<string, string> kv in env) psi.EnvironmentVariables[kv.Key] = kv.Value;
            }
            proc = Process.Start(psi);
            proc.OutputDataReceived += (s, e) => Log(e.Data);
            proc.ErrorDataReceived += (s, e) => Log(e.Data);
            proc.BeginOutputReadLine();
            proc.BeginErrorReadLine();
            try
            {
                Wait.Until(() => proc.HasExited || StatusOrNull() != null, StartupSeconds, "GET /api/status to answer");
                Assert.IsFalse(proc.HasExited, "safestate run exited: " + Output());
                Wait.Until(() => { var s = StatusOrNull(); return s != null && (s["state"] as string) != "BOOT"; },
                           StartupSeconds, "the end of BOOT");
            }
            catch
            {
                Dispose();
                throw;
            }
        }

        /// <summary>A cell whose pendant needs `token`, given to `safestate run` in
        /// SAFESTATE_PENDANT_TOKEN (never on its command line).</summary>
        public static Cell WithPendantToken(string token)
        {
            var cell = new Cell("", new Dictionary<string, string> { { "SAFESTATE_PENDANT_TOKEN", token } });
            try
            {
                Assert.IsTrue(cell.PendantNeedsToken(), "SAFESTATE_PENDANT_TOKEN did not make the pendant need a token");
            }
            catch
            {
                cell.Dispose();
                throw;
            }
            return cell;
        }

        private bool PendantNeedsToken()
        {
            var c = new SafeStateClient(new ClientOptions { UseSynchronizationContext = false, AutoReconnect = false });
            try
            {
                c.ConnectAsync(Ws, Role.pendant).Wait(10000);
                return false;
            }
            catch (AggregateException e)
            {
                var refused = e.InnerException as ConnectException;
                if (refused != null && refused.ServerCode == "BAD_TOKEN") return true;
                throw;
            }
            finally
            {
                c.Dispose();
            }
        }

        public int Port { get; private set; }
        public Uri Ws { get { return new Uri("ws://127.0.0.1:" + Port + "/ws"); } }
        public Uri Http { get { return new Uri("http://127.0.0.1:" + Port + "/"); } }

        public static string Bin
        {
            get
            {
                string b = Environment.GetEnvironmentVariable("SAFESTATE_BIN");
                if (!string.IsNullOrEmpty(b)) return b;
                // clients/csharp/bin/ -> build/bin/safestate
                string here = Path.GetDirectoryName(typeof(Cell).Assembly.Location);
                return Path.GetFullPath(Path.Combine(here, "..", "..", "..", "build", "bin", "safestate"));
            }
        }

        public static int FreePort()
        {
            var l = new TcpListener(IPAddress.Loopback, 0);
            l.Start();
            int port = ((IPEndPoint)l.LocalEndpoint).Port;
            l.Stop();
            return port;
        }

        private void Log(string line)
        {
            if (line == null) return;
            lock (log)
            {
                if (log.Length < 200000) log.AppendLine(line);
            }
        }

        public string Output()
        {
            lock (log) return log.ToString();
        }

        /// <summary>GET /api/status, or null when it does not answer.</summary>
        public JsonObject StatusOrNull()
        {
            try
            {
                var req = (HttpWebRequest)WebRequest.Create(new Uri(Http, "api/status"));
                req.Timeout = 1000;
                using (var r = (HttpWebResponse)req.GetResponse())
                using (var rd = new StreamReader(r.GetResponseStream()))
                {
                    return Json.Parse(rd.ReadToEnd()) as JsonObject;
                }
            }
            catch (Exception)
            {
                return null;
            }
        }

        public long GatewayPid()
        {
            JsonObject s = StatusOrNull();
            Assert.IsNotNull(s, "GET /api/status");
            Assert.IsInstanceOf<long>(s["gateway_pid"], "status.gateway_pid");
            return (long)s["gateway_pid"];
        }

        public static void Signal(long pid, string signal)
        {
            using (Process k = Process.Start(new ProcessStartInfo("kill", "-" + signal + " " + pid) { UseShellExecute = false }))
            {
                k.WaitForExit();
                Assert.AreEqual(0, k.ExitCode, "kill -" + signal + " " + pid);
            }
        }

        public void Dispose()
        {
            try
            {
                if (!proc.HasExited)
                {
                    Signal(proc.Id, "INT");
                    if (!proc.WaitForExit(10000)) proc.Kill();
                }
                proc.WaitForExit();
            }
            finally
            {
                try { Directory.Delete(dir, true); } catch (Exception) { /* a leftover temp dir is harmless */ }
            }
        }
    }

    internal static class Wait
    {
        public static void Until(Func<bool> condition, double seconds, string what)
        {
            var sw = Stopwatch.StartNew();
            while (!condition())
            {
                if (sw.Elapsed.TotalSeconds > seconds) Assert.Fail("timeout (" + seconds + " s) waiting for " + what);
                Thread.Sleep(20);
            }
        }

        public static T Result<T>(Task<T> t, double seconds, string what)
        {
            if (!t.Wait(TimeSpan.FromSeconds(seconds))) Assert.Fail("timeout (" + seconds + " s) waiting for " + what);
            return t.Result;
        }

        public static void Done(Task t, double seconds, string what)
        {
            if (!t.Wait(TimeSpan.FromSeconds(seconds))) Assert.Fail("timeout (" + seconds + " s) waiting for " + what);
        }

        /// <summary>Waits for a status (from the client's stream) that satisfies pred.</summary>
        public static StatusMessage Status(SafeStateClient c, Func<StatusMessage, bool> pred, string what, double seconds = 10)
        {
            StatusMessage found = null;
            Until(() => { var s = c.LastStatus; if (s != null && pred(s)) found = s; return found != null; }, seconds, what);
            return found;
        }

        public static StatusMessage State(SafeStateClient c, State state, SubState? sub = null)
        {
            return Status(c, s => s.State == state && (sub == null || s.Sub == sub),
                          "state " + state + (sub.HasValue ? " " + sub : ""));
        }
    }

    /// <summary>A client plus a record of everything it raised.</summary>
    internal sealed class Recorder
    {
        public readonly List<ClientError> Errors = new List<ClientError>();
        public readonly List<EventMessage> Events = new List<EventMessage>();
        public readonly List<ConnectionState> Links = new List<ConnectionState>();
        public int Statuses;

        public Recorder(SafeStateClient c)
        {
            c.Error += (s, e) => { lock (Errors) Errors.Add(e); };
            c.Event += (s, e) => { lock (Events) Events.Add(e); };
            c.ConnectionChanged += (s, e) => { lock (Links) Links.Add(e); };
            c.Status += (s, e) => Interlocked.Increment(ref Statuses);
        }

        public List<ClientError> ErrorsOf(ClientErrorKind kind)
        {
            lock (Errors) return Errors.FindAll(e => e.Kind == kind);
        }

        public List<EventMessage> EventsWhere(Predicate<EventMessage> p)
        {
            lock (Events) return Events.FindAll(p);
        }
    }
}
