// SafeState.Console as a user runs it: a process, commands on stdin, replies on stdout.
using System;
using System.Collections.Generic;
using System.Diagnostics;
using System.IO;
using System.Linq;
using System.Threading.Tasks;
using NUnit.Framework;

namespace SafeState.Tests
{
    [TestFixture]
    public class ConsoleTests
    {
        private static string Here
        {
            get { return Path.GetDirectoryName(typeof(ConsoleTests).Assembly.Location); }
        }

        // Under Mono (make test) the console is SafeState.Console.exe run by mono; under
        // `dotnet test` (SafeState.Tests.csproj) it is SafeState.Console.dll run by dotnet.
        private static ProcessStartInfo ConsoleProcess(string args)
        {
            bool mono = Type.GetType("Mono.Runtime") != null;
            return mono ? new ProcessStartInfo("mono", "\"" + Path.Combine(Here, "SafeState.Console.exe") + "\" " + args)
                        : new ProcessStartInfo("dotnet", "\"" + Path.Combine(Here, "SafeState.Console.dll") + "\" " + args);
        }

        private static int Run(string args, string stdin, out string stdout, out string stderr, int timeoutMs = 60000,
                               string pendantToken = null)
        {
            ProcessStartInfo psi = ConsoleProcess(args);
            psi.UseShellExecute = false;
            psi.RedirectStandardInput = true;
            psi.RedirectStandardOutput = true;
            psi.RedirectStandardError = true;
            psi.EnvironmentVariables.Remove("SAFESTATE_PENDANT_TOKEN");
            psi.EnvironmentVariables.Remove("SAFESTATE_REMOTE_TOKEN");
            if (pendantToken != null) psi.EnvironmentVariables["SAFESTATE_PENDANT_TOKEN"] = pendantToken;
            using (Process p = Process.Start(psi))
            {
                var err = p.StandardError.ReadToEndAsync();
                var outp = p.StandardOutput.ReadToEndAsync();
                p.StandardInput.Write(stdin);
                p.StandardInput.Close();
                if (!p.WaitForExit(timeoutMs))
                {
                    p.Kill();
                    Assert.Fail("the console did not exit");
                }
                stdout = outp.Result;
                stderr = err.Result;
                return p.ExitCode;
            }
        }

        [Test]
        public void RunsAScriptAndPrintsOneReplyLinePerCommand()
        {
            using (var cell = new Cell())
            {
                string script = string.Join("\n",
                    "# an AUTO cycle, then the observer's view",
                    "wait state=ESTOP_RESET_NEEDED",
                    "reset",
                    "servo_on",
                    "wait state=OPERATIONAL sub=AUTO_IDLE",
                    "start",
                    "wait sub=AUTO_RUNNING",
                    "stop       # a Cat 2 stop back to AUTO_IDLE",
                    "wait sub=AUTO_IDLE",
                    "cmd servo_off",
                    "set_mode T1",
                    "wait state=IDLE",
                    "in estop.a=0",
                    "wait state=ESTOP_ACTIVE",
                    "alarms",
                    "history",
                    "");
                string stdout, stderr;
                int code = Run("--url " + cell.Ws + " --role pendant --live", script, out stdout, out stderr);
                Assert.AreEqual(0, code, stdout + stderr);
                // --live with stderr redirected: one status line per change, and the events.
                StringAssert.IsMatch("status t=[0-9]+ OPERATIONAL/AUTO_RUNNING mode=AUTO", stderr);
                StringAssert.IsMatch("status t=[0-9]+ ESTOP_ACTIVE mode=AUTO .*alarms=ESTOP_PRESSED", stderr);
                StringAssert.Contains("event #", stderr);
                Assert.IsFalse(stdout.Contains("status t="), "stdout stays machine-readable");
                string[] replies = stdout.Split('\n').Where(l => l.StartsWith("reply ")).ToArray();
                CollectionAssert.AreEqual(new[]
                {
                    "reply 1 reset OK", "reply 2 servo_on OK", "reply 3 start OK", "reply 4 stop OK", "reply 5 servo_off OK",
                    "reply 6 set_mode MODE_BY_SELECTOR_ONLY", "reply 7 in OK",
                }, replies, stdout + stderr);
                StringAssert.Contains("alarm ESTOP_PRESSED (301, info", stdout);
                StringAssert.Contains("history ", stdout);
                StringAssert.IsMatch("history [0-9]+ events, last id [0-9]+", stdout);
                StringAssert.Contains("connected to safestate", stderr);
            }
        }

        [Test]
        public void RepliesPrintInTheOrderOfTheCommandsWhenTheServerAnswersOutOfOrder()
        {
            // A reset is answered up to 50 cycles late, after commands sent behind it (SPEC §5);
            // the client completes replies on the thread pool. A script's stdout must still list
            // its replies in command order, or no two runs of one script print the same.
            using (var stub = new StubServer())
            {
                Task server = Task.Run(async () =>
                {
                    await StubTests.Welcome(stub);
                    var seqs = new List<long>();
                    for (int i = 0; i < 3; ++i) seqs.Add(StubTests.SeqOf(await stub.ReceiveAsync()));
                    string[] results = { "OK", "BUSY", "WRONG_STATE" };
                    for (int i = 2; i >= 0; --i)
                    {
                        await stub.SendText("{\"type\":\"reply\",\"seq\":" + seqs[i] + ",\"result\":\"" + results[i] + "\"}");
                        await Task.Delay(20);  // three frames, the last command's answer first
                    }
                });
                string stdout, stderr;
                int code = Run("--url " + stub.Ws + " --role pendant", "reset\nservo_on\nstart\n", out stdout, out stderr);
                Assert.IsTrue(server.Wait(5000), "the stub finished");
                Assert.AreEqual(0, code, stdout + stderr);
                string[] replies = stdout.Split('\n').Where(l => l.StartsWith("reply ")).ToArray();
                CollectionAssert.AreEqual(new[] { "reply 1 reset OK", "reply 2 servo_on BUSY", "reply 3 start WRONG_STATE" },
                                          replies, stdout + stderr);
            }
        }

        [Test]
        public void ObserverRepliesAndExitCodes()
        {
            using (var cell = new Cell())
            {
                string stdout, stderr;
                int code = Run("--url " + cell.Ws + " --role observer", "reset\njog 1 + 5\n", out stdout, out stderr);
                Assert.AreEqual(0, code, stdout + stderr);
                StringAssert.Contains("reply 1 reset NOT_CONTROL_OWNER", stdout);
                StringAssert.Contains("reply 2 jog NOT_CONTROL_OWNER", stdout);
                // A malformed line is named and makes the exit status 2; the rest still runs.
                code = Run("--url " + cell.Ws + " --role observer", "jog 9 +\nreset\n", out stdout, out stderr);
                Assert.AreEqual(2, code, stdout + stderr);
                StringAssert.Contains("line 1:", stderr);
                StringAssert.Contains("reply 1 reset NOT_CONTROL_OWNER", stdout);
                // A wait that times out is exit status 1.
                code = Run("--url " + cell.Ws + " --role observer", "wait state=OPERATIONAL timeout=0.3\n", out stdout, out stderr);
                Assert.AreEqual(1, code, stdout + stderr);
                StringAssert.StartsWith("wait timeout", stdout);
            }
        }

        [Test]
        public void TokenFromAFileOrTheEnvironmentNeverFromTheCommandLine()
        {
            string file = Path.GetTempFileName();
            try
            {
                using (Cell cell = Cell.WithPendantToken("s3cret-token"))
                {
                    string stdout, stderr;
                    File.WriteAllText(file, "s3cret-token\n");  // the trailing newline is stripped
                    int code = Run("--url " + cell.Ws + " --role pendant --token-file " + file, "reset\n", out stdout, out stderr);
                    Assert.AreEqual(0, code, stdout + stderr);
                    StringAssert.Contains("reply 1 reset OK", stdout);
                    Assert.IsFalse((stdout + stderr).Contains("s3cret-token"), "the token is never printed");

                    File.WriteAllText(file, "wrong\n");
                    code = Run("--url " + cell.Ws + " --role pendant --token-file " + file, "reset\n", out stdout, out stderr);
                    Assert.AreEqual(2, code, stdout + stderr);
                    StringAssert.Contains("BAD_TOKEN", stderr);

                    code = Run("--url " + cell.Ws + " --role pendant", "reset\n", out stdout, out stderr);
                    Assert.AreEqual(2, code, "no token: refused");
                    StringAssert.Contains("BAD_TOKEN", stderr);

                    code = Run("--url " + cell.Ws + " --role pendant", "reset\n", out stdout, out stderr, 60000, "s3cret-token");
                    Assert.AreEqual(0, code, "SAFESTATE_PENDANT_TOKEN: " + stdout + stderr);
                }
            }
            finally
            {
                File.Delete(file);
            }
        }

        [Test]
        public void RefusesATokenOnTheCommandLineAndAnUnreachableServer()
        {
            string stdout, stderr;
            int code = Run("--url ws://127.0.0.1:1/ws --role pendant --token s3cret", "", out stdout, out stderr);
            Assert.AreEqual(2, code);
            StringAssert.Contains("--token-file", stderr);
            code = Run("--url ws://127.0.0.1:" + Cell.FreePort() + "/ws --role pendant", "reset\n", out stdout, out stderr);
            Assert.AreEqual(2, code, stderr);
            StringAssert.Contains("cannot connect", stderr);
            code = Run("--url http://x/ --role pendant", "", out stdout, out stderr);
            Assert.AreEqual(2, code);
            code = Run("--url ws://127.0.0.1:1/ws --role king", "", out stdout, out stderr);
            Assert.AreEqual(2, code);
        }
    }
}
