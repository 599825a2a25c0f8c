// Bad server input, from a stub server, never throws into the application: every case is
// an Error event raised on the application's (UI) thread, and the client keeps working.
using System;
using System.Collections.Concurrent;
using System.Collections.Generic;
using System.Diagnostics;
using System.Linq;
using System.Text;
using System.Threading;
using System.Threading.Tasks;
using NUnit.Framework;
using SafeState.Client;

namespace SafeState.Tests
{
    /// <summary>A UI thread's message loop in miniature: posted callbacks run in order on
    /// one thread, and an exception escaping one is recorded (a WPF app would crash).</summary>
    internal sealed class UiThread : SynchronizationContext, IDisposable
    {
        private readonly BlockingCollection<KeyValuePair<SendOrPostCallback, object>> queue =
            new BlockingCollection<KeyValuePair<SendOrPostCallback, object>>();
        private readonly Thread thread;
        public readonly List<Exception> Escaped = new List<Exception>();

        public UiThread()
        {
            thread = new Thread(Loop) { IsBackground = true, Name = "ui" };
            thread.Start();
        }

        public int ThreadId { get { return thread.ManagedThreadId; } }

        private void Loop()
        {
            SetSynchronizationContext(this);
            foreach (var item in queue.GetConsumingEnumerable())
            {
                try
                {
                    item.Key(item.Value);
                }
                catch (Exception e)
                {
                    lock (Escaped) Escaped.Add(e);
                }
            }
        }

        public override void Post(SendOrPostCallback d, object state)
        {
            queue.Add(new KeyValuePair<SendOrPostCallback, object>(d, state));
        }

        public T Run<T>(Func<T> f)
        {
            var done = new TaskCompletionSource<T>();
            Post(_ =>
            {
                try { done.SetResult(f()); } catch (Exception e) { done.SetException(e); }
            }, null);
            return SafeState.Tests.Wait.Result(done.Task, 10, "the UI thread");
        }

        public void Dispose()
        {
            queue.CompleteAdding();
        }
    }

    [TestFixture]
    public class StubTests
    {
        private const string ValidStatus =
            "{\"type\":\"status\",\"t\":5,\"state\":\"IDLE\",\"sub\":null,\"mode\":\"T1\",\"stop\":null,\"contactor\":\"open\"," +
            "\"drives\":\"disabled\",\"brakes\":\"engaged\",\"reset_lamp\":\"on\",\"tcp_speed\":0,\"alarms\":[\"PROTECTIVE_STOP\"]," +
            "\"joints\":[0,0,0,0,0,0],\"tcp\":[1,2,3,0,0,0],\"t2_confirmed\":false,\"owner\":\"pendant\"}";

        internal static async Task Welcome(StubServer stub)
        {
            await stub.AcceptAsync().ConfigureAwait(false);
            string hello = await stub.ReceiveAsync().ConfigureAwait(false);
            var h = (JsonObject)Json.Parse(hello);
            Assert.AreEqual("hello", h["type"]);
            await stub.SendText("{\"type\":\"welcome\",\"role\":\"" + h["role"] + "\",\"server\":\"stub 1\"}").ConfigureAwait(false);
        }

        internal static long SeqOf(string command)
        {
            return (long)((JsonObject)Json.Parse(command))["seq"];
        }

        [Test]
        public void BadFramesRaiseErrorOnTheUiThreadAndNeverThrow()
        {
            using (var ui = new UiThread())
            using (var stub = new StubServer())
            {
                SafeStateClient client = ui.Run(() => new SafeStateClient(new ClientOptions { AutoReconnect = false }));
                var errors = new List<ClientError>();
                var statuses = new List<StatusMessage>();
                var offThread = 0;
                ui.Run(() =>
                {
                    client.Error += (s, x) => { if (Thread.CurrentThread.ManagedThreadId != ui.ThreadId) ++offThread; errors.Add(x); };
                    client.Status += (s, x) => { if (Thread.CurrentThread.ManagedThreadId != ui.ThreadId) ++offThread; statuses.Add(x); };
                    // An application handler that throws is reported, not propagated.
                    client.Status += (s, x) => { if (x.T == 6) throw new InvalidOperationException("app bug"); };
                    return 0;
                });
                Task server = Task.Run(async () =>
                {
                    await Welcome(stub);
                    await stub.SendText("{not json");
                    await stub.SendText("[1,2,3]");
                    await stub.SendText("{\"type\":\"no_such_type\"}");
                    await stub.SendText("{\"type\":\"status\",\"t\":1}");                               // fields missing
                    await stub.SendText(ValidStatus.Replace("\"t\":5", "\"t\":\"five\""));               // mistyped
                    await stub.SendText(ValidStatus.Replace("\"IDLE\"", "\"DANCING\""));                 // unknown state
                    await stub.SendText(ValidStatus.Replace("\"t\":5,", "\"t\":5,\"t\":6,"));             // duplicate key
                    await stub.SendText(new string('[', 100) + new string(']', 100));                  // too deep
                    await stub.SendText("{\"type\":\"reply\",\"seq\":999999,\"result\":\"OK\"}");     // nobody's seq
                    await stub.SendText("{\"type\":\"error\",\"code\":\"BAD_MESSAGE\",\"detail\":\"x\"}");
                    await stub.SendText("{\"type\":\"error\",\"code\":\"NOPE\",\"detail\":\"x\"}");      // unknown code
                    await stub.SendText("{\"type\":\"status\"," + new string(' ', 100 * 1024) + "\"t\":1}"); // oversize
                    await stub.SendBinary(new byte[] { 1, 2, 3 });
                    await stub.SendText(ValidStatus.Replace("\"t\":5,", "\"t\":6,\"colour\":\"red\",")); // unknown field: still used
                    await stub.SendText(ValidStatus);
                    string cmd = await stub.ReceiveAsync();
                    long seq = SeqOf(cmd);
                    await stub.SendText("{\"type\":\"reply\",\"seq\":" + (seq + 1000) + ",\"result\":\"BUSY\"}");
                    await stub.SendText("{\"type\":\"reply\",\"seq\":" + seq + ",\"result\":\"GATE_OPEN\"}");
                    string second = await stub.ReceiveAsync();
                    await stub.SendText("{\"type\":\"reply\",\"seq\":" + SeqOf(second) + ",\"result\":\"PERHAPS\"}"); // unknown result
                });
                Wait.Done(client.ConnectAsync(stub.Ws, Role.pendant), 10, "connect to the stub");
                try
                {
                    Wait.Until(() => ui.Run(() => statuses.Count) >= 2, 10, "the two valid statuses after the bad frames");
                }
                catch (AssertionException)
                {
                    Console.WriteLine(string.Join("\n", ui.Run(() => errors.ToList()).Select(x => x.ToString())));
                    throw;
                }
                Assert.AreEqual(Result.GATE_OPEN, Wait.Result(client.SendAsync(Command.Start()), 10, "the reply to its own seq"));
                var bad = client.SendAsync(Command.Stop());
                var e = Assert.Throws<AggregateException>(() => bad.Wait(10000));
                Assert.AreEqual(CommandFailure.BadReply, ((CommandFailedException)e.InnerException).Reason);
                Wait.Done(server, 10, "the stub's script");
                Thread.Sleep(100);

                List<ClientError> seen = ui.Run(() => errors.ToList());
                Func<ClientErrorKind, int> count = k => seen.Count(x => x.Kind == k);
                string all = string.Join("\n", seen.Select(x => x.ToString()));
                Assert.AreEqual(3, count(ClientErrorKind.BadJson), all);        // {not json, duplicate key, too deep
                Assert.AreEqual(7, count(ClientErrorKind.BadMessage), all);     // array, type, missing, mistyped, state, unknown code, result
                Assert.AreEqual(1, count(ClientErrorKind.TooLarge), all);
                Assert.AreEqual(1, count(ClientErrorKind.BinaryFrame), all);
                Assert.AreEqual(2, count(ClientErrorKind.UnexpectedReply), all);
                Assert.AreEqual(1, count(ClientErrorKind.ServerError), all);
                Assert.AreEqual(1, count(ClientErrorKind.UnknownField), all);
                Assert.AreEqual(1, count(ClientErrorKind.HandlerFailed), all);
                StringAssert.Contains("colour", seen.Single(x => x.Kind == ClientErrorKind.UnknownField).Message);
                Assert.AreEqual("BAD_MESSAGE", seen.Single(x => x.Kind == ClientErrorKind.ServerError).ServerCode);

                List<StatusMessage> st = ui.Run(() => statuses.ToList());
                Assert.AreEqual(2, st.Count, "only the two valid statuses came through");
                Assert.AreEqual(6, st[0].T);
                Assert.AreEqual(State.IDLE, st[1].State);
                Assert.AreEqual(Mode.T1, st[1].Mode);
                CollectionAssert.AreEqual(new[] { "PROTECTIVE_STOP" }, st[1].Alarms);
                Assert.AreEqual(0, ui.Run(() => offThread), "every event is raised on the UI thread");
                lock (ui.Escaped) Assert.IsEmpty(ui.Escaped, "nothing escaped into the UI thread");
                Assert.AreEqual(ConnectionState.Connected, client.State, "bad frames do not end the link");
                client.Dispose();
            }
        }

        [Test]
        public void InvalidUtf8FailsTheLinkAndTheClientReconnectsWithoutResending()
        {
            // RFC 6455 8.1: a text frame that is not UTF-8 fails the connection (Mono's
            // ClientWebSocket does so itself). The client reports it and reconnects; the
            // command that was waiting fails and is not sent again on the new link.
            using (var stub = new StubServer())
            {
                var client = new SafeStateClient(new ClientOptions { UseSynchronizationContext = false });
                var rec = new Recorder(client);
                string onSecondLink = null;
                Task server = Task.Run(async () =>
                {
                    await Welcome(stub);
                    await stub.ReceiveAsync();  // the start: never answered on this link
                    await stub.SendRawText(new byte[] { (byte)'"', 0xC3, 0x28, (byte)'"' });
                    await Welcome(stub);        // the reconnect
                    onSecondLink = await stub.ReceiveAsync();
                    await stub.SendText("{\"type\":\"reply\",\"seq\":" + SeqOf(onSecondLink) + ",\"result\":\"OK\"}");
                });
                Wait.Done(client.ConnectAsync(stub.Ws, Role.pendant), 10, "connect");
                var start = client.SendAsync(Command.Start());
                var e = Assert.Throws<AggregateException>(() => start.Wait(10000));
                Assert.AreEqual(CommandFailure.Disconnected, ((CommandFailedException)e.InnerException).Reason);
                Wait.Until(() => client.State == ConnectionState.Connected && client.Reconnects == 1, 10, "the reconnect");
                Assert.AreEqual(Result.OK, Wait.Result(client.SendAsync(Command.Reset()), 10, "a command on the new link"));
                Wait.Done(server, 10, "the stub");
                StringAssert.Contains("\"cmd\":\"reset\"", onSecondLink, "the first message on the new link is the new command, not the start");
                Assert.AreEqual(1, rec.ErrorsOf(ClientErrorKind.Disconnected).Count);
                client.Dispose();
            }
        }

        [Test]
        public void SafetyStatusAndConfigValidatedEventAreTyped()
        {
            // SPEC §10: the status `safety` object and the `config_validated` event of the gateway
            // (protocol.md) are read, not refused nor reported as unknown.
            const string safety =
                ",\"safety\":{\"checksum\":\"3AD9012B\",\"validated\":false,\"reduced\":true,\"reduced_by\":[\"zone\",\"input\"]," +
                "\"recovery\":false,\"speed_limit\":250.0,\"v_allowed\":null,\"fields\":{\"outer\":\"clear\",\"inner\":\"clear\"}," +
                "\"separation_mm\":null,\"brake_test\":{\"due_in_h\":null,\"last\":\"none\"}}}";
            using (var stub = new StubServer())
            {
                var client = new SafeStateClient(new ClientOptions { UseSynchronizationContext = false });
                var rec = new Recorder(client);
                StatusMessage last = null;
                client.Status += (s, e) => last = e;
                Task server = Task.Run(async () =>
                {
                    await Welcome(stub);
                    await stub.SendText(ValidStatus.Substring(0, ValidStatus.Length - 1) + safety);
                    await stub.SendText("{\"type\":\"event\",\"id\":9,\"t\":5,\"time\":\"2026-11-25T08:00:00.123Z\"," +
                                        "\"kind\":\"config_validated\",\"data\":{\"checksum\":\"3AD9012B\",\"client\":\"hmi\",\"role\":\"pendant\"}}");
                    await stub.SendText(ValidStatus.Substring(0, ValidStatus.Length - 1) + safety.Replace("3AD9012B", "3AD9012"));
                });
                Wait.Done(client.ConnectAsync(stub.Ws, Role.pendant), 10, "connect");
                Wait.Done(server, 10, "the stub");
                Wait.Until(() => rec.EventsWhere(e => e.Kind == EventKind.config_validated).Count == 1 &&
                                 rec.ErrorsOf(ClientErrorKind.BadMessage).Count == 1, 10, "the event and the bad checksum");
                Assert.IsNotNull(last.Safety);
                Assert.AreEqual("3AD9012B", last.Safety.Checksum);
                Assert.IsFalse(last.Safety.Validated);
                Assert.IsTrue(last.Safety.Reduced);
                CollectionAssert.AreEqual(new[] { "zone", "input" }, last.Safety.ReducedBy);
                Assert.AreEqual(250.0, last.Safety.SpeedLimit);
                Assert.IsNull(last.Safety.VAllowed);
                Assert.IsNull(last.Safety.SeparationMm);
                Assert.AreEqual(false, last.Safety.OuterFieldInterrupted);
                Assert.AreEqual(false, last.Safety.InnerFieldInterrupted);
                Assert.IsFalse(last.Safety.Pfl, "absent: a gateway without collision detection");
                Assert.IsNull(last.Safety.ContactForce);
                Assert.IsEmpty(rec.ErrorsOf(ClientErrorKind.UnknownField), "every field of the safety object is known");
                StringAssert.Contains("checksum", rec.ErrorsOf(ClientErrorKind.BadMessage)[0].Message);
                EventMessage ev = rec.EventsWhere(e => e.Kind == EventKind.config_validated)[0];
                Assert.AreEqual("3AD9012B", ev.Data["checksum"]);
                StringAssert.Contains("3AD9012B validated by hmi", ev.Line());
                client.Dispose();
            }
        }

        [Test]
        public void CollaborativeSafetyFieldsAreTyped()
        {
            // SPEC §11: the fields, SSM's separation and v_allowed, PFL and the contact force
            // (views.cpp's additions after protocol.md's fields) are typed; a wrong type or a
            // wrong word refuses the message.
            const string safety =
                ",\"safety\":{\"checksum\":\"3AD9012B\",\"validated\":true,\"reduced\":true,\"reduced_by\":[\"field\"]," +
                "\"recovery\":false,\"speed_limit\":250.0,\"v_allowed\":344.8,\"fields\":{\"outer\":\"interrupted\",\"inner\":\"clear\"}," +
                "\"separation_mm\":800,\"brake_test\":{\"due_in_h\":null,\"last\":\"none\"}," +
                "\"pfl\":true,\"contact_force\":12.5,\"contact_force_limit\":140.0,\"pfl_speed_limit\":1348.2}}";
            Recorder rec;
            List<StatusMessage> got = StatusesWithSafety(new[]
            {
                safety,
                safety.Replace("\"interrupted\"", "\"broken\""),
                safety.Replace("\"contact_force\":12.5", "\"contact_force\":\"12.5\""),
                safety.Replace("\"pfl\":true", "\"pfl\":1"),
                safety.Replace("\"v_allowed\":344.8", "\"v_allowed\":-1"),
            }, 4, out rec);
            Assert.AreEqual(1, got.Count, "only the good status is delivered");
            StatusMessage last = got[0];
            SafetyStatus sf = last.Safety;
            Assert.AreEqual(344.8, sf.VAllowed);
            Assert.AreEqual(800.0, sf.SeparationMm);
            Assert.AreEqual(true, sf.OuterFieldInterrupted);
            Assert.AreEqual(false, sf.InnerFieldInterrupted);
            Assert.IsTrue(sf.Pfl);
            Assert.AreEqual(12.5, sf.ContactForce);
            Assert.AreEqual(140.0, sf.ContactForceLimit);
            Assert.AreEqual(1348.2, sf.PflSpeedLimit);
            Assert.IsEmpty(rec.ErrorsOf(ClientErrorKind.UnknownField), "every field of the safety object is known");
            var bad = rec.ErrorsOf(ClientErrorKind.BadMessage);
            StringAssert.Contains("status.safety.fields: \"outer\" must be \"clear\" or \"interrupted\"", bad[0].Message);
            StringAssert.Contains("\"contact_force\" must be a number or null", bad[1].Message);
            StringAssert.Contains("\"pfl\" must be true, false or null", bad[2].Message);
            StringAssert.Contains("\"v_allowed\" must be a number >= 0 or null", bad[3].Message);
        }

        /// <summary>One status per `safety` object (the text after ValidStatus' last field) from a
        /// stub gateway; waits until `refused` of them were refused as bad messages, and returns
        /// the others as delivered, in order.</summary>
        private static List<StatusMessage> StatusesWithSafety(string[] safeties, int refused, out Recorder rec)
        {
            using (var stub = new StubServer())
            {
                var client = new SafeStateClient(new ClientOptions { UseSynchronizationContext = false });
                var r = new Recorder(client);
                var got = new List<StatusMessage>();
                client.Status += (s, e) => { lock (got) got.Add(e); };
                string head = ValidStatus.Substring(0, ValidStatus.Length - 1);
                Task server = Task.Run(async () =>
                {
                    await Welcome(stub);
                    foreach (string sf in safeties) await stub.SendText(head + sf);
                });
                Wait.Done(client.ConnectAsync(stub.Ws, Role.pendant), 10, "connect");
                Wait.Done(server, 10, "the stub");
                Wait.Until(() => r.ErrorsOf(ClientErrorKind.BadMessage).Count == refused, 10, refused + " refused");
                client.Dispose();
                rec = r;
                lock (got) return new List<StatusMessage>(got);
            }
        }

        [Test]
        public void SimulatedPersonIsTyped()
        {
            // SPEC §11: status.sim (views.cpp status_sim_json), the person and the simulated
            // devices' fields, typed; null sim and null person read; a wrong type, a negative
            // radius or a point outside 0..7 refuses the message.
            const string fields = "\"person_fields\":{\"outer_mm\":2000,\"inner_mm\":1000,\"scanner\":true,\"distance_sensor\":true}";
            const string person = "\"person\":{\"x_mm\":0,\"y_mm\":800,\"radius_mm\":250,\"speed_mm_s\":1600,\"walking\":false," +
                                  "\"in_outer\":true,\"in_inner\":true,\"separation_mm\":412.5,\"nearest_point\":7}";
            string present = ",\"sim\":{" + person + "," + fields + "}}";
            Recorder rec;
            List<StatusMessage> got = StatusesWithSafety(new[]
            {
                present,
                ",\"sim\":{\"person\":null," + fields + "}}",
                ",\"sim\":null}",
                present.Replace("\"walking\":false", "\"walking\":\"no\""),
                present.Replace("\"radius_mm\":250", "\"radius_mm\":-250"),
                present.Replace("\"nearest_point\":7", "\"nearest_point\":8"),
                present.Replace("\"scanner\":true", "\"scanner\":1"),
            }, 4, out rec);
            Assert.AreEqual(3, got.Count, "only the good ones are delivered");
            SimStatus sim = got[0].Sim;
            Assert.IsNotNull(sim);
            Assert.AreEqual(2000.0, sim.OuterFieldMm);
            Assert.AreEqual(1000.0, sim.InnerFieldMm);
            Assert.IsTrue(sim.Scanner && sim.DistanceSensor);
            Assert.AreEqual(800.0, sim.Person.YMm);
            Assert.AreEqual(1600.0, sim.Person.SpeedMmS);
            Assert.IsFalse(sim.Person.Walking);
            Assert.IsTrue(sim.Person.InOuterField && sim.Person.InInnerField);
            Assert.AreEqual(412.5, sim.Person.SeparationMm);
            Assert.AreEqual(7, sim.Person.NearestPoint);
            Assert.IsNull(got[1].Sim.Person, "nobody in the cell");
            Assert.IsNull(got[2].Sim, "not the in-process simulated cell");
            Assert.IsEmpty(rec.ErrorsOf(ClientErrorKind.UnknownField), "sim is a known field");
            var bad = rec.ErrorsOf(ClientErrorKind.BadMessage);
            StringAssert.Contains("status.sim.person: \"walking\" must be true or false", bad[0].Message);
            StringAssert.Contains("\"radius_mm\" must be a number >= 0", bad[1].Message);
            StringAssert.Contains("\"nearest_point\" must be an integer 0..7", bad[2].Message);
            StringAssert.Contains("status.sim.person_fields: \"scanner\" must be true or false", bad[3].Message);
        }

        [Test]
        public void BrakeTestStatusIsTyped()
        {
            // SPEC §12: safety.brake_test, protocol.md's due_in_h and last and the gateway's
            // additions (views.cpp), typed; a wrong word, axis, progress or drift list refuses the
            // message; protocol.md's two fields alone read with the others at their defaults.
            const string head =
                ",\"safety\":{\"checksum\":\"3AD9012B\",\"validated\":true,\"reduced\":false,\"reduced_by\":[]," +
                "\"recovery\":false,\"speed_limit\":1500.0,\"v_allowed\":null,\"brake_test\":";
            const string failed =
                "{\"due_in_h\":-1.25,\"last\":\"failed\",\"running\":false,\"axis\":null,\"progress\":null,\"due\":true," +
                "\"required\":true,\"last_time\":\"2026-11-27T06:30:00.000Z\",\"last_axis\":3,\"drift_deg\":[0.01,0.02,1.2,0,0,0]}";
            const string running =
                "{\"due_in_h\":null,\"last\":\"none\",\"running\":true,\"axis\":2,\"progress\":25,\"due\":false," +
                "\"required\":false,\"last_time\":null,\"last_axis\":null,\"drift_deg\":null}";
            Recorder rec;
            List<StatusMessage> got = StatusesWithSafety(new[]
            {
                head + failed + "}}",
                head + running + "}}",
                head + "{\"due_in_h\":5.2,\"last\":\"passed\"}}}",
                head + failed.Replace("\"failed\"", "\"maybe\"") + "}}",
                head + running.Replace("\"axis\":2", "\"axis\":7") + "}}",
                head + running.Replace("\"progress\":25", "\"progress\":101") + "}}",
                head + failed.Replace("1.2,0,0,0]", "1.2,0,0]") + "}}",
                head + failed.Replace("[0.01,", "[-0.01,") + "}}",
            }, 5, out rec);
            Assert.AreEqual(3, got.Count, "only the good ones are delivered");
            BrakeTestStatus f = got[0].Safety.BrakeTest;
            Assert.AreEqual(-1.25, f.DueInHours);
            Assert.AreEqual("failed", f.Last);
            Assert.IsFalse(f.Running);
            Assert.IsNull(f.Axis);
            Assert.IsNull(f.Progress);
            Assert.IsTrue(f.Due);
            Assert.IsTrue(f.Required);
            Assert.AreEqual("2026-11-27T06:30:00.000Z", f.LastTime);
            Assert.AreEqual(3, f.LastAxis);
            CollectionAssert.AreEqual(new[] { 0.01, 0.02, 1.2, 0, 0, 0 }, f.DriftDeg);
            Assert.AreEqual("overdue by 1.3 h, last failed axis 3", f.Line());
            BrakeTestStatus r = got[1].Safety.BrakeTest;
            Assert.IsTrue(r.Running);
            Assert.AreEqual(2, r.Axis);
            Assert.AreEqual(25, r.Progress);
            Assert.IsNull(r.DueInHours);
            Assert.IsNull(r.DriftDeg);
            Assert.AreEqual("running axis 2 (25 %)", r.Line());
            BrakeTestStatus p = got[2].Safety.BrakeTest;
            Assert.AreEqual(5.2, p.DueInHours);
            Assert.AreEqual("passed", p.Last);
            Assert.IsFalse(p.Running || p.Due || p.Required);
            Assert.IsNull(p.LastAxis);
            Assert.IsNull(p.DriftDeg);
            Assert.AreEqual("due in 5.2 h, last passed", p.Line());
            Assert.IsEmpty(rec.ErrorsOf(ClientErrorKind.UnknownField));
            var bad = rec.ErrorsOf(ClientErrorKind.BadMessage);
            StringAssert.Contains("status.safety.brake_test: \"last\" must be \"none\", \"passed\" or \"failed\"", bad[0].Message);
            StringAssert.Contains("\"axis\" must be an axis 1..6 or null", bad[1].Message);
            StringAssert.Contains("\"progress\" must be an integer 0..100 or null", bad[2].Message);
            StringAssert.Contains("\"drift_deg\" must be an array of 6 numbers", bad[3].Message);
            StringAssert.Contains("\"drift_deg\" must be an array of 6 numbers >= 0 or null", bad[4].Message);
        }

        [Test]
        public void RepliesOutOfOrderCompleteTheirOwnCommands()
        {
            // A reset that acknowledges drive faults is answered up to 50 cycles late, after
            // commands sent behind it (SPEC §5): a reply goes to its seq, not to the oldest.
            using (var stub = new StubServer())
            {
                var client = new SafeStateClient(new ClientOptions { UseSynchronizationContext = false });
                var rec = new Recorder(client);
                Task server = Task.Run(async () =>
                {
                    await Welcome(stub);
                    var seqs = new List<long>();
                    for (int i = 0; i < 3; ++i) seqs.Add(SeqOf(await stub.ReceiveAsync()));
                    string[] results = { "FAULT_PRESENT", "BUSY", "WRONG_STATE" };
                    for (int i = 2; i >= 0; --i)
                    {
                        await stub.SendText("{\"type\":\"reply\",\"seq\":" + seqs[i] + ",\"result\":\"" + results[i] + "\"}");
                    }
                });
                Wait.Done(client.ConnectAsync(stub.Ws, Role.pendant), 10, "connect");
                PendingCommand a = client.Submit(Command.Reset());
                PendingCommand b = client.Submit(Command.ServoOn());
                PendingCommand c = client.Submit(Command.Start());
                Assert.AreEqual(Result.WRONG_STATE, Wait.Result(c.Reply, 10, "start"));
                Assert.AreEqual(Result.BUSY, Wait.Result(b.Reply, 10, "servo_on"));
                Assert.AreEqual(Result.FAULT_PRESENT, Wait.Result(a.Reply, 10, "reset"));
                Assert.IsTrue(a.Seq < b.Seq && b.Seq < c.Seq, "seqs grow in sending order");
                Wait.Done(server, 5, "the stub");
                Assert.IsEmpty(rec.ErrorsOf(ClientErrorKind.UnexpectedReply));
                client.Dispose();
            }
        }

        [Test]
        public void AFloodOfBadFramesIsCountedNotPostedOneByOne()
        {
            using (var stub = new StubServer())
            {
                var client = new SafeStateClient(new ClientOptions { UseSynchronizationContext = false, MaxErrorsPerSecond = 20 });
                var rec = new Recorder(client);
                var floodAccounted = new TaskCompletionSource<bool>();
                Task server = Task.Run(async () =>
                {
                    await Welcome(stub);
                    for (int i = 0; i < 300; ++i) await stub.SendText("{bad " + i);
                    await stub.SendText(ValidStatus);
                    await floodAccounted.Task;
                    await stub.SendText("{bad again");
                    await stub.SendText(ValidStatus.Replace("\"t\":5", "\"t\":7"));
                });
                Wait.Done(client.ConnectAsync(stub.Ws, Role.observer), 10, "connect");
                Wait.Status(client, s => s.T == 5, "the status after the flood");
                // Every bad frame is either raised or counted in an "N more" error, and far fewer
                // than 300 reach the application (20 per second and kind). The count of the last
                // window comes when that window ends, without waiting for another bad frame:
                // however long the flood takes to read (a loaded host), nothing goes unaccounted.
                var more = new System.Text.RegularExpressions.Regex("^([0-9]+) more BadJson errors");
                int counted = 0, raised = 0;
                string all = "";
                var clock = Stopwatch.StartNew();
                do
                {
                    if (counted + raised > 0) Thread.Sleep(50);
                    List<ClientError> flood = rec.ErrorsOf(ClientErrorKind.BadJson);
                    counted = raised = 0;
                    foreach (ClientError x in flood)
                    {
                        var m = more.Match(x.Message);
                        if (m.Success) counted += int.Parse(m.Groups[1].Value);
                        else ++raised;
                    }
                    all = string.Join("\n", flood.Select(x => x.Message).Take(40));
                } while (raised + counted < 300 && clock.ElapsedMilliseconds < 10000);
                Assert.AreEqual(300, raised + counted, all);
                Assert.Less(raised, 100, all);
                Assert.Greater(counted, 0, all);
                // The flood's windows have ended (their counts came): the next bad frame is raised.
                floodAccounted.SetResult(true);
                Wait.Status(client, s => s.T == 7, "the status after the next bad frame");
                Wait.Done(server, 10, "the stub");
                List<ClientError> bad = rec.ErrorsOf(ClientErrorKind.BadJson);
                StringAssert.Contains("{bad again", bad[bad.Count - 1].Message);
                client.Dispose();
            }
        }

        [Test]
        public void AbruptCloseFailsPendingCommandsAndNeverHangs()
        {
            using (var stub = new StubServer())
            {
                var client = new SafeStateClient(new ClientOptions { AutoReconnect = false, UseSynchronizationContext = false });
                var rec = new Recorder(client);
                Task server = Task.Run(async () =>
                {
                    await Welcome(stub);
                    await stub.ReceiveAsync();  // the command: never answered
                    stub.Drop();
                });
                Wait.Done(client.ConnectAsync(stub.Ws, Role.pendant), 10, "connect");
                var pending = client.SendAsync(Command.Jog(1, '+'));
                var e = Assert.Throws<AggregateException>(() => pending.Wait(10000));
                var f = (CommandFailedException)e.InnerException;
                Assert.AreEqual(CommandFailure.Disconnected, f.Reason, f.Message);
                Wait.Done(server, 5, "the stub");
                Wait.Until(() => client.State == ConnectionState.Disconnected, 5, "Disconnected");
                var after = client.SendAsync(Command.Reset());
                e = Assert.Throws<AggregateException>(() => after.Wait(1000));
                Assert.AreEqual(CommandFailure.NotConnected, ((CommandFailedException)e.InnerException).Reason);
                Assert.AreEqual(1, rec.ErrorsOf(ClientErrorKind.Disconnected).Count);
                client.Dispose();
            }
        }

        [Test]
        public void UnansweredCommandTimesOut()
        {
            using (var stub = new StubServer())
            {
                var client = new SafeStateClient(new ClientOptions
                {
                    AutoReconnect = false,
                    UseSynchronizationContext = false,
                    CommandTimeout = TimeSpan.FromMilliseconds(300),
                });
                Task server = Task.Run(async () =>
                {
                    await Welcome(stub);
                    await stub.ReceiveAsync();
                });
                Wait.Done(client.ConnectAsync(stub.Ws, Role.remote), 10, "connect");
                var sw = System.Diagnostics.Stopwatch.StartNew();
                var e = Assert.Throws<AggregateException>(() => client.SendAsync(Command.ServoOn()).Wait(10000));
                Assert.AreEqual(CommandFailure.Timeout, ((CommandFailedException)e.InnerException).Reason);
                Assert.Less(sw.ElapsedMilliseconds, 5000);
                Wait.Done(server, 5, "the stub");
                client.Dispose();
            }
        }

        [Test]
        public void RefusedHelloFailsConnectWithTheServersCode()
        {
            using (var stub = new StubServer())
            {
                var client = new SafeStateClient(new ClientOptions { UseSynchronizationContext = false });
                Task server = Task.Run(async () =>
                {
                    await stub.AcceptAsync();
                    var hello = (JsonObject)Json.Parse(await stub.ReceiveAsync());
                    Assert.AreEqual("s3cret", hello["token"]);
                    await stub.SendText("{\"type\":\"error\",\"code\":\"BAD_TOKEN\",\"detail\":\"wrong token\"}");
                });
                var e = Assert.Throws<AggregateException>(() => client.ConnectAsync(stub.Ws, Role.pendant, "s3cret").Wait(10000));
                Assert.AreEqual("BAD_TOKEN", ((ConnectException)e.InnerException).ServerCode);
                Assert.AreEqual(ConnectionState.Disconnected, client.State);
                Wait.Done(server, 5, "the stub");
                client.Dispose();
            }
        }
    }
}
