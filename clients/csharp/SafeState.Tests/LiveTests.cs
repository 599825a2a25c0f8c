// The library against a real `safestate run` (simulated cell) on a free loopback port.
using System;
using System.Collections.Generic;
using System.Diagnostics;
using System.Linq;
using System.Threading;
using System.Threading.Tasks;
using NUnit.Framework;
using SafeState.Client;

namespace SafeState.Tests
{
    [TestFixture]
    public class LiveTests
    {
        private Cell cell;
        private readonly List<SafeStateClient> clients = new List<SafeStateClient>();

        [SetUp]
        public void StartCell()
        {
            cell = new Cell();
        }

        [TearDown]
        public void StopCell()
        {
            foreach (SafeStateClient c in clients) c.Dispose();
            clients.Clear();
            if (cell != null) cell.Dispose();
        }

        private SafeStateClient Connect(Role role, ClientOptions options = null)
        {
            var c = new SafeStateClient(options ?? new ClientOptions { UseSynchronizationContext = false });
            clients.Add(c);
            Wait.Done(c.ConnectAsync(cell.Ws, role), 10, "connect as " + role);
            return c;
        }

        private static Result Send(SafeStateClient c, Command cmd)
        {
            return Wait.Result(c.SendAsync(cmd), 10, "the reply to " + cmd);
        }

        private static void Sim(SafeStateClient c, string key, string value)
        {
            Assert.AreEqual(Result.OK, Wait.Result(c.SimAsync(new JsonObject().Set(key, value)), 10, "sim " + key));
        }

        private static SafeStateClient ToT1ManualIdle(SafeStateClient p)
        {
            Sim(p, "mode", "T1");
            Wait.Status(p, s => s.Mode == Mode.T1, "mode T1");
            Sim(p, "enable", "centre");  // after the mode change: held across it, it would not enable (SPEC §2)
            Wait.State(p, State.ESTOP_RESET_NEEDED);
            Assert.AreEqual(Result.OK, Send(p, Command.Reset()));
            Wait.State(p, State.IDLE);
            Assert.AreEqual(Result.OK, Send(p, Command.ServoOn()));
            Wait.State(p, State.OPERATIONAL, SubState.MANUAL_IDLE);
            return p;
        }

        [Test]
        public void HelloAsEachRoleIsWelcomedAndStatusIsTyped()
        {
            foreach (Role role in new[] { Role.observer, Role.remote, Role.pendant })
            {
                SafeStateClient c = Connect(role);
                Assert.AreEqual(ConnectionState.Connected, c.State, role.ToString());
                Assert.AreEqual(role, c.Role);
                StringAssert.StartsWith("safestate ", c.Server);
                StatusMessage s = Wait.Status(c, x => true, "a status as " + role);
                Assert.AreEqual(6, s.Joints.Length);
                Assert.AreEqual(6, s.Tcp.Length);
                Assert.AreEqual(6, s.AxisStates.Count);
                Assert.IsTrue(s.State == State.ESTOP_RESET_NEEDED, "after BOOT with the E-stop released: " + s.Line());
                Assert.AreEqual(Mode.AUTO, s.Mode);
                Assert.IsFalse(s.ContactorClosed);
                Assert.IsNull(s.Sub);
                // SPEC §11 from the real gateway (built-in configuration: no collaborative operation).
                Assert.IsNotNull(s.Safety);
                Assert.AreEqual(false, s.Safety.OuterFieldInterrupted);
                Assert.AreEqual(false, s.Safety.InnerFieldInterrupted);
                Assert.IsNull(s.Safety.VAllowed);
                Assert.IsNull(s.Safety.SeparationMm);
                Assert.IsFalse(s.Safety.Pfl);
                Assert.IsNull(s.Safety.ContactForce);
                Assert.IsNull(s.Safety.ContactForceLimit);
                Assert.IsNull(s.Safety.PflSpeedLimit);
                // SPEC §12: a fresh event log, the built-in configuration: none on record, none required.
                Assert.IsNotNull(s.Safety.BrakeTest);
                Assert.AreEqual("none", s.Safety.BrakeTest.Last);
                Assert.IsNull(s.Safety.BrakeTest.DueInHours);
                Assert.IsFalse(s.Safety.BrakeTest.Running || s.Safety.BrakeTest.Required);
                Assert.IsNull(s.Safety.BrakeTest.DriftDeg);
            }
            // A second pendant is refused with the server's code; ConnectAsync says so.
            var second = new SafeStateClient(new ClientOptions { UseSynchronizationContext = false });
            clients.Add(second);
            var e = Assert.Throws<AggregateException>(() => second.ConnectAsync(cell.Ws, Role.pendant).Wait(10000));
            var refused = e.InnerException as ConnectException;
            Assert.IsNotNull(refused, e.ToString());
            Assert.AreEqual("ROLE_TAKEN", refused.ServerCode);
            Assert.AreEqual(ConnectionState.Disconnected, second.State);
        }

        [Test]
        public void FullAutoCycle()
        {
            SafeStateClient p = Connect(Role.pendant);
            var rec = new Recorder(p);
            Wait.State(p, State.ESTOP_RESET_NEEDED);
            Assert.AreEqual(Result.OK, Send(p, Command.Reset()));
            Wait.State(p, State.IDLE);
            Assert.AreEqual(Result.WRONG_STATE, Send(p, Command.Start()));
            Assert.AreEqual(Result.OK, Send(p, Command.ServoOn()));
            StatusMessage s = Wait.State(p, State.OPERATIONAL, SubState.AUTO_IDLE);
            Assert.IsTrue(s.ContactorClosed && s.DrivesEnabled && s.BrakesReleased, s.Line());
            Assert.AreEqual(Role.pendant, s.Owner);
            Assert.AreEqual(Result.OK, Send(p, Command.Start()));
            Wait.Status(p, x => x.Sub == SubState.AUTO_RUNNING && x.TcpSpeed > 0, "the program moving the arm");
            Assert.AreEqual(Result.OK, Send(p, Command.Pause()));
            Wait.State(p, State.OPERATIONAL, SubState.AUTO_PAUSED);
            Assert.AreEqual(Result.OK, Send(p, Command.Resume()));
            Wait.State(p, State.OPERATIONAL, SubState.AUTO_RUNNING);
            Assert.AreEqual(Result.OK, Send(p, Command.Stop()));
            Wait.State(p, State.OPERATIONAL, SubState.AUTO_IDLE);
            Assert.AreEqual(Result.OK, Send(p, Command.ServoOff()));
            s = Wait.State(p, State.IDLE);
            Assert.IsFalse(s.ContactorClosed || s.DrivesEnabled || s.BrakesReleased, s.Line());
            // The events came typed: the transitions of the cycle and every command with its result.
            Wait.Until(() => rec.EventsWhere(e => e.Kind == EventKind.command && e.Cmd == "servo_off").Count == 1, 5, "servo_off event");
            Assert.IsNotEmpty(rec.EventsWhere(e => e.Kind == EventKind.transition && e.To == "AUTO_PAUSED"));
            Assert.AreEqual(Result.WRONG_STATE, rec.EventsWhere(e => e.Kind == EventKind.command && e.Cmd == "start")[0].Result);
            Assert.IsEmpty(rec.ErrorsOf(ClientErrorKind.BadMessage), "no message of the real server is refused");
            Assert.IsEmpty(rec.ErrorsOf(ClientErrorKind.BadJson));
        }

        [Test]
        public void T1JogThroughTheHelperMovesWhileHeldAndStopsWhenReleased()
        {
            SafeStateClient p = ToT1ManualIdle(Connect(Role.pendant));
            double[] before = p.LastStatus.Joints;
            JogHold hold = p.HoldJog(1, '+', 10);
            Assert.AreEqual(Result.OK, Wait.Result(hold.First, 5, "the first jog"));
            StatusMessage moving = Wait.Status(p, s => s.Sub == SubState.MANUAL_JOGGING && Math.Abs(s.Joints[0] - before[0]) > 0.01,
                                               "axis 1 moving");
            Assert.LessOrEqual(moving.TcpSpeed, 250.0, "T1 reduced speed");
            for (int i = 1; i < 6; ++i) Assert.AreEqual(before[i], moving.Joints[i], 1e-3, "only axis 1 jogs");
            // Held for many times jog_timeout_ms: the keep-alive keeps the jog going.
            Thread.Sleep(600);
            StatusMessage still = p.LastStatus;
            Assert.AreEqual(SubState.MANUAL_JOGGING, still.Sub, still.Line());
            Assert.IsTrue(hold.Active, "hold ended: " + hold.EndReason);
            Assert.GreaterOrEqual(hold.Sent, 8, "a keep-alive about every 40 ms");

            Assert.AreEqual(Result.OK, Wait.Result(hold.ReleaseAsync(), 5, "jog_stop"));
            Assert.IsFalse(hold.Active);
            StatusMessage idle = Wait.State(p, State.OPERATIONAL, SubState.MANUAL_IDLE);
            CollectionAssert.DoesNotContain(idle.Alarms, "JOG_LINK_LOST", "stopped by jog_stop, not by the keep-alive timeout");
            // Released means released: no more jog commands, and the arm stays where it stopped.
            int sent = hold.Sent;
            long total = p.Sent;
            double q = idle.Joints[0];
            Thread.Sleep(300);
            Assert.AreEqual(sent, hold.Sent);
            Assert.AreEqual(total, p.Sent);
            Assert.AreEqual(q, p.LastStatus.Joints[0], 1e-4);
            Assert.AreEqual(SubState.MANUAL_IDLE, p.LastStatus.Sub);
        }

        [Test]
        public void JogHoldRefusedInAutoEndsByItself()
        {
            SafeStateClient p = Connect(Role.pendant);
            var rec = new Recorder(p);
            Wait.State(p, State.ESTOP_RESET_NEEDED);
            JogHold hold = p.HoldJog(2, '-', 5);
            Assert.AreEqual(Result.RESET_REQUIRED, Wait.Result(hold.First, 5, "the first jog"));
            Wait.Until(() => !hold.Active, 2, "the hold to end");
            StringAssert.Contains("RESET_REQUIRED", hold.EndReason);
            Thread.Sleep(200);
            Assert.AreEqual(1, hold.Sent, "a refused jog is not repeated");
            Assert.AreEqual(1, rec.ErrorsOf(ClientErrorKind.JogStopped).Count);
        }

        [Test]
        public void ThousandCommandsEachCompleteExactlyOnceWithTheirOwnReply()
        {
            SafeStateClient p = Connect(Role.pendant);
            var rec = new Recorder(p);
            Wait.State(p, State.ESTOP_RESET_NEEDED);
            const int n = 1000;
            // Two commands whose answers differ in this state, so a reply given to the wrong
            // seq shows: set_mode is always MODE_BY_SELECTOR_ONLY, servo_on is RESET_REQUIRED.
            var window = new SemaphoreSlim(32);  // below the gateway's 64 in flight per client
            var completions = new int[n];
            var results = new Result?[n];
            var failures = new Exception[n];
            var seqs = new long[n];
            var all = new Task[n];
            var sw = Stopwatch.StartNew();
            for (int i = 0; i < n; ++i)
            {
                Assert.IsTrue(window.Wait(10000), "window");
                int k = i;
                PendingCommand pc = p.Submit(i % 2 == 0 ? Command.SetMode(Mode.T1) : Command.ServoOn());
                seqs[k] = pc.Seq;
                all[k] = pc.Reply.ContinueWith(t =>
                {
                    Interlocked.Increment(ref completions[k]);
                    if (t.Status == TaskStatus.RanToCompletion) results[k] = t.Result;
                    else failures[k] = t.Exception;
                    window.Release();
                });
            }
            Assert.IsTrue(Task.WaitAll(all, 60000), "every command completes");
            Console.WriteLine("1000 commands in " + sw.ElapsedMilliseconds + " ms");
            Assert.AreEqual(n, seqs.Distinct().Count(), "one seq per command");
            // The gateway lets each client put at most 250 records a second on the core's ring
            // (a bucket of 64, protocol.md "Fairness"): beyond it the answer is QUEUE_FULL, the
            // gateway's own. Every other answer must be the core's answer to that very command.
            int answeredByCore = 0;
            for (int i = 0; i < n; ++i)
            {
                Assert.AreEqual(1, completions[i], "command " + i + " completed once");
                Assert.IsNull(failures[i], "command " + i);
                if (results[i] == Result.QUEUE_FULL) continue;
                Assert.AreEqual(i % 2 == 0 ? Result.MODE_BY_SELECTOR_ONLY : Result.RESET_REQUIRED, results[i], "command " + i);
                ++answeredByCore;
            }
            Assert.GreaterOrEqual(answeredByCore, 64, "at least the rate limit's bucket reaches the core");
            Thread.Sleep(200);
            Assert.IsEmpty(rec.ErrorsOf(ClientErrorKind.UnexpectedReply), "no reply without its command");
            Assert.AreEqual(State.ESTOP_RESET_NEEDED, p.LastStatus.State, "refused commands changed nothing");
        }

        [Test]
        public void ObserverCommandIsNotControlOwnerAndChangesNothing()
        {
            SafeStateClient o = Connect(Role.observer);
            Wait.State(o, State.ESTOP_RESET_NEEDED);
            Assert.AreEqual(Result.NOT_CONTROL_OWNER, Send(o, Command.Reset()));
            Assert.AreEqual(Result.NOT_CONTROL_OWNER, Send(o, Command.ServoOn()));
            Assert.AreEqual(Result.NOT_CONTROL_OWNER, Send(o, Command.Jog(1, '+')));
            Thread.Sleep(100);
            Assert.AreEqual(State.ESTOP_RESET_NEEDED, o.LastStatus.State);
        }

        [Test]
        public void ReconnectsAfterKill9OfTheGatewayWithoutResendingMotion()
        {
            var options = new ClientOptions { UseSynchronizationContext = false, CommandTimeout = TimeSpan.FromSeconds(3) };
            SafeStateClient p = ToT1ManualIdle(Connect(Role.pendant, options));
            var rec = new Recorder(p);
            JogHold hold = p.HoldJog(1, '-', 10);
            Assert.AreEqual(Result.OK, Wait.Result(hold.First, 5, "the first jog"));
            Wait.State(p, State.OPERATIONAL, SubState.MANUAL_JOGGING);
            long gw = cell.GatewayPid();

            Cell.Signal(gw, "KILL");
            // A command sent into the dying link completes with a clear error, never hangs.
            var late = p.SendAsync(Command.Start());
            var failure = Assert.Throws<AggregateException>(() => late.Wait(8000), "no reply can come");
            Assert.IsInstanceOf<CommandFailedException>(failure.InnerException, failure.ToString());
            Wait.Until(() => !hold.Active, 5, "the jog hold to end with the link");
            long sentAtLoss = p.Sent;

            Wait.Until(() => p.State == ConnectionState.Connected && p.Reconnects == 1, 30, "the client to reconnect");
            Assert.AreNotEqual(gw, cell.GatewayPid(), "safestate run restarted its gateway");
            CollectionAssert.Contains(rec.Links, ConnectionState.Reconnecting);
            Assert.IsNotEmpty(rec.ErrorsOf(ClientErrorKind.Disconnected));
            // The core stopped the jog by its own keep-alive timeout; nothing moves again.
            StatusMessage s = Wait.Status(p, x => x.Sub == SubState.MANUAL_IDLE, "the jog stopped by the core");
            Thread.Sleep(500);
            Assert.AreEqual(sentAtLoss, p.Sent, "nothing was sent after the link was lost: no motion re-sent");
            Assert.AreEqual(SubState.MANUAL_IDLE, p.LastStatus.Sub);
            Assert.AreEqual(s.Joints[0], p.LastStatus.Joints[0], 1e-4, "the arm stays where it stopped");

            // The history agrees: no jog or start reached the core after the kill.
            using (var h = new HistoryClient(cell.Http))
            {
                var cmds = new List<EventMessage>();
                EventPager pager = h.Events(0, 100);
                for (IReadOnlyList<EventMessage> page; (page = Wait.Result(pager.NextAsync(), 10, "a page")).Count > 0;)
                {
                    cmds.AddRange(page.Where(e => e.Kind == EventKind.command));
                }
                Assert.IsEmpty(cmds.Where(e => e.Cmd == "start"), "the start sent into the dead link never reached the core");
                int jogs = cmds.Count(e => e.Cmd == "jog");
                Assert.That(jogs, Is.GreaterThan(0).And.LessThanOrEqualTo(hold.Sent), "every jog the core took was sent once by the hold");
            }
            // The new link works: the operator asks again, explicitly.
            Assert.AreEqual(Result.OK, Send(p, Command.ServoOff()));
            Wait.State(p, State.IDLE);
        }

        [Test]
        public void HistoryPagerWalksEveryEventOnceInOrder()
        {
            SafeStateClient p = Connect(Role.pendant);
            Wait.State(p, State.ESTOP_RESET_NEEDED);
            Assert.AreEqual(Result.OK, Send(p, Command.Reset()));
            Assert.AreEqual(Result.OK, Send(p, Command.ServoOn()));
            Wait.State(p, State.OPERATIONAL, SubState.AUTO_IDLE);
            Assert.AreEqual(Result.OK, Send(p, Command.ServoOff()));
            Wait.State(p, State.IDLE);
            using (var h = new HistoryClient(HistoryClient.BaseOf(cell.Ws)))
            {
                IReadOnlyList<EventMessage> all = null;
                Wait.Until(() => (all = Wait.Result(h.GetEventsAsync(0, 500), 10, "events")).Count >= 6, 5, "6 events");
                var walked = new List<EventMessage>();
                EventPager pager = h.Events(0, 2);
                int pages = 0;
                for (IReadOnlyList<EventMessage> page; (page = Wait.Result(pager.NextAsync(), 10, "a page")).Count > 0;)
                {
                    Assert.LessOrEqual(page.Count, 2);
                    walked.AddRange(page);
                    ++pages;
                }
                Assert.GreaterOrEqual(pages, 3);
                CollectionAssert.AreEqual(all.Select(e => e.Id).ToList(), walked.Take(all.Count).Select(e => e.Id).ToList());
                CollectionAssert.IsOrdered(walked.Select(e => e.Id.Value).ToList());
                Assert.AreEqual(walked.Count, walked.Select(e => e.Id).Distinct().Count());
                Assert.IsTrue(walked.Any(e => e.Kind == EventKind.command && e.Cmd == "servo_on" && e.Result == Result.OK));
                IReadOnlyList<AlarmEntry> alarms = Wait.Result(h.GetAlarmsAsync(), 10, "alarms");
                Assert.IsEmpty(alarms, "no alarm in IDLE after a clean servo_off");
            }
            Assert.AreEqual(Result.OK, Wait.Result(p.SimAsync(new JsonObject().Set("estop.a", 0L)), 5, "E-stop channel A"));
            Wait.State(p, State.ESTOP_ACTIVE);
            using (var h = new HistoryClient(cell.Http))
            {
                AlarmEntry a = Wait.Result(h.GetAlarmsAsync(), 10, "alarms").Single(x => x.Name == "ESTOP_PRESSED");
                Assert.AreEqual(AlarmName.ESTOP_PRESSED, a.Known);
                Assert.AreEqual(Alarms.Info(AlarmName.ESTOP_PRESSED).Number, a.Number);
                Assert.AreEqual(Severity.info, a.Severity);
                // The E-stop (a stop) has a black box, served apart from the page.
                EventMessage stop = null;
                Wait.Until(() => (stop = Wait.Result(h.GetEventsAsync(0, 500), 10, "events")
                                      .LastOrDefault(e => e.BlackBoxUrl != null)) != null, 5, "an event with a black box");
                StringAssert.StartsWith("/api/events/" + stop.Id + "/blackbox", stop.BlackBoxUrl);
                object box = Wait.Result(h.GetBlackBoxAsync(stop), 10, "the black box");
                Assert.IsTrue(box is List<object> || box is JsonObject, "a black box is JSON data: " + box);
            }
        }

        [Test]
        public void SimRefusedIsAClearErrorNotAHang()
        {
            SafeStateClient p = Connect(Role.pendant);
            var refused = p.SimAsync(new JsonObject().Set("estop", "squashed"));
            var e = Assert.Throws<AggregateException>(() => refused.Wait(5000));
            var f = e.InnerException as CommandFailedException;
            Assert.IsNotNull(f, e.ToString());
            Assert.AreEqual(CommandFailure.Refused, f.Reason);
            StringAssert.Contains("BAD_MESSAGE", f.Message);
        }
    }
}
