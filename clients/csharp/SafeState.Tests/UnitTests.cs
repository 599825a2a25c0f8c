// The strict JSON reader, the generated names and the .scn command spelling, alone.
using System;
using System.Collections.Generic;
using System.Linq;
using NUnit.Framework;
using SafeState.Client;

namespace SafeState.Tests
{
    [TestFixture]
    public class JsonTests
    {
        [TestCase("{}")]
        [TestCase("[]")]
        [TestCase(" {\"a\" : [1, -2, 3.5, 1e3, -0.5E-2, true, false, null, \"x\"]} ")]
        [TestCase("\"\\u00e9\\ud83d\\ude00\\n\\\"\\\\\\/\"")]
        [TestCase("0")]
        [TestCase("-0")]
        public void AcceptsValidJson(string text)
        {
            Assert.DoesNotThrow(() => Json.Parse(text));
        }

        [TestCase("", TestName = "empty")]
        [TestCase("{not json}")]
        [TestCase("{\"a\":1,}")]
        [TestCase("[1,]")]
        [TestCase("[1 2]")]
        [TestCase("{\"a\" 1}")]
        [TestCase("{'a':1}")]
        [TestCase("{\"a\":1}x")]
        [TestCase("{\"a\":1}{}")]
        [TestCase("{\"a\":1,\"a\":2}", TestName = "duplicate key")]
        [TestCase("01")]
        [TestCase("1.")]
        [TestCase(".5")]
        [TestCase("1e")]
        [TestCase("+1")]
        [TestCase("NaN")]
        [TestCase("Infinity")]
        [TestCase("1e999", TestName = "out of range")]
        [TestCase("tru")]
        [TestCase("nul")]
        [TestCase("\"abc")]
        [TestCase("\"a\\qb\"")]
        [TestCase("\"\\u12\"")]
        [TestCase("\"\\ud800\"", TestName = "lone high surrogate escape")]
        [TestCase("\"\\udc00\"", TestName = "lone low surrogate escape")]
        [TestCase("\"a\tb\"", TestName = "raw control character")]
        public void RefusesInvalidJson(string text)
        {
            Assert.Throws<JsonException>(() => Json.Parse(text));
        }

        [Test]
        public void RefusesNestingDeeperThanTheLimit()
        {
            string ok = new string('[', Json.MaxDepth) + new string(']', Json.MaxDepth);
            Assert.DoesNotThrow(() => Json.Parse(ok));
            string deep = new string('[', Json.MaxDepth + 2) + new string(']', Json.MaxDepth + 2);
            Assert.Throws<JsonException>(() => Json.Parse(deep));
        }

        [Test]
        public void RefusesALoneSurrogateCharacter()
        {
            Assert.Throws<JsonException>(() => Json.Parse("\"a\ud800b\""));
        }

        [Test]
        public void TypesNumbersAndKeepsKeyOrder()
        {
            var o = (JsonObject)Json.Parse("{\"z\":1,\"a\":2.5,\"m\":-9223372036854775808,\"big\":9223372036854775808,\"n\":null}");
            CollectionAssert.AreEqual(new[] { "z", "a", "m", "big", "n" }, o.Keys);
            Assert.AreEqual(1L, o["z"]);
            Assert.AreEqual(2.5, o["a"]);
            Assert.AreEqual(long.MinValue, o["m"]);
            Assert.IsInstanceOf<double>(o["big"], "beyond long: a double");
            Assert.IsTrue(o.Has("n"));
            Assert.IsNull(o["n"]);
            Assert.IsFalse(o.Has("q"));
        }

        [Test]
        public void WritesWhatItReads()
        {
            var o = new JsonObject().Set("type", "command").Set("seq", 17L).Set("s", "a\"b\\c\n\u0001é")
                                    .Set("l", new List<object> { 1L, 2.5, true, null });
            string text = Json.Write(o);
            Assert.AreEqual("{\"type\":\"command\",\"seq\":17,\"s\":\"a\\\"b\\\\c\\n\\u0001é\",\"l\":[1,2.5,true,null]}", text);
            var back = (JsonObject)Json.Parse(text);
            Assert.AreEqual("a\"b\\c\n\u0001é", back["s"]);
            Assert.Throws<JsonException>(() => Json.Write(double.NaN));
        }
    }

    [TestFixture]
    public class NamesTests
    {
        [Test]
        public void EveryGeneratedNameRoundTrips()
        {
            AssertRoundTrip<State>(8);
            AssertRoundTrip<SubState>(7);  // SPEC §12 adds BRAKE_TEST
            AssertRoundTrip<Mode>(4);
            AssertRoundTrip<StopCategory>(3);
            AssertRoundTrip<Result>(23);
            AssertRoundTrip<CommandName>(13);  // SPEC §12 adds brake_test
            AssertRoundTrip<Role>(3);
            AssertRoundTrip<Severity>(4);
            AssertRoundTrip<AxisState>(8);
            AssertRoundTrip<Cia402State>(8);
            AssertRoundTrip<ErrorCode>(6);
            AssertRoundTrip<EventKind>(6);  // protocol.md: transition, alarm, alarm_cleared, command, config_validated, brake_test
            AssertRoundTrip<AlarmName>(Alarms.Table.Length);
        }

        private static void AssertRoundTrip<T>(int count) where T : struct
        {
            IReadOnlyList<string> names = Wire.Names<T>();
            Assert.AreEqual(count, names.Count, typeof(T).Name);
            Assert.AreEqual(count, Enum.GetValues(typeof(T)).Length, typeof(T).Name);
            foreach (string n in names)
            {
                T v;
                Assert.IsTrue(Wire.TryParse(n, out v), typeof(T).Name + " " + n);
                Assert.AreEqual(n, Wire.Name(v));
            }
        }

        [Test]
        public void DocumentedTypesExist()
        {
            // docs/csharp.md maps SPEC names to C# types; every type it names must exist.
            string dir = System.IO.Path.GetDirectoryName(typeof(NamesTests).Assembly.Location);
            while (dir != null && !System.IO.File.Exists(System.IO.Path.Combine(dir, "docs", "csharp.md")))
            {
                dir = System.IO.Path.GetDirectoryName(dir);
            }
            Assert.IsNotNull(dir, "docs/csharp.md not found above the test assembly");
            string doc = System.IO.File.ReadAllText(System.IO.Path.Combine(dir, "docs", "csharp.md"));
            var names = System.Text.RegularExpressions.Regex.Matches(doc, "`SafeState\\.Client\\.([A-Za-z0-9]+)`")
                .Cast<System.Text.RegularExpressions.Match>().Select(m => m.Groups[1].Value).Distinct().ToList();
            Assert.GreaterOrEqual(names.Count, 20, "the mapping table");
            foreach (string n in names)
            {
                Assert.IsNotNull(typeof(SafeStateClient).Assembly.GetType("SafeState.Client." + n), "docs/csharp.md names SafeState.Client." + n);
            }
        }

        [Test]
        public void ParsingIsExact()
        {
            State s;
            Result r;
            Assert.IsFalse(Wire.TryParse("idle", out s), "case-sensitive");
            Assert.IsFalse(Wire.TryParse("4", out s), "no numbers");
            Assert.IsFalse(Wire.TryParse(" IDLE", out s));
            Assert.IsFalse(Wire.TryParse(null, out r));
            Cia402State c;
            Assert.IsTrue(Wire.TryParse("Operation enabled", out c));
            Assert.AreEqual(Cia402State.Operation_enabled, c);
            Assert.IsFalse(Wire.TryParse("Operation_enabled", out c), "the wire name has spaces");
        }

        [Test]
        public void SpecNamesAndAlarmTable()
        {
            // Spot checks against SPEC.md, independent of the generator.
            CollectionAssert.AreEqual(new[] { "BOOT", "ERROR_LOCKOUT", "ESTOP_ACTIVE", "ESTOP_RESET_NEEDED", "IDLE", "ARMING", "OPERATIONAL", "STOPPING" },
                                      Wire.Names<State>());
            CollectionAssert.Contains(Wire.Names<Result>(), "NOT_CONTROL_OWNER");
            CollectionAssert.Contains(Wire.Names<Result>(), "QUEUE_FULL");
            CollectionAssert.AreEqual(new[] { "pendant", "remote", "observer" }, Wire.Names<Role>());
            AlarmInfo e = Alarms.Info(AlarmName.ESTOP_PRESSED);
            Assert.AreEqual(301, e.Number);
            Assert.AreEqual(301, (int)AlarmName.ESTOP_PRESSED, "the enum value is the alarm number");
            Assert.AreEqual(Severity.info, e.Severity);
            Assert.AreEqual(AlarmLatch.Condition, e.Latch);
            Assert.AreEqual(Severity.lockout, Alarms.Info(AlarmName.FIELDBUS_LOST).Severity);
            Assert.AreEqual(AlarmLatch.Reset, Alarms.Info(AlarmName.PROTECTIVE_STOP).Latch);
            Assert.AreEqual(AlarmLatch.UntilOk, Alarms.Info(AlarmName.JOG_LINK_LOST).Latch);
            Assert.AreEqual(Alarms.Table.Length, Alarms.Table.Select(a => a.Number).Distinct().Count(), "numbers are unique");
            foreach (AlarmInfo a in Alarms.Table)
            {
                Assert.IsNotEmpty(a.Text, a.Name.ToString());
                Assert.IsNotEmpty(a.Remedy, a.Name.ToString());
            }
        }
    }

    [TestFixture]
    public class CommandTests
    {
        [TestCase("reset", "{\"type\":\"command\",\"seq\":7,\"cmd\":\"reset\"}")]
        [TestCase("  servo_on ", "{\"type\":\"command\",\"seq\":7,\"cmd\":\"servo_on\"}")]
        [TestCase("jog 1 + 10", "{\"type\":\"command\",\"seq\":7,\"cmd\":\"jog\",\"axis\":1,\"dir\":\"+\",\"speed\":10}")]
        [TestCase("jog 6 -", "{\"type\":\"command\",\"seq\":7,\"cmd\":\"jog\",\"axis\":6,\"dir\":\"-\",\"speed\":10}")]
        [TestCase("jog 3 - 100", "{\"type\":\"command\",\"seq\":7,\"cmd\":\"jog\",\"axis\":3,\"dir\":\"-\",\"speed\":100}")]
        [TestCase("set_mode T2", "{\"type\":\"command\",\"seq\":7,\"cmd\":\"set_mode\",\"mode\":\"T2\"}")]
        [TestCase("confirm_t2", "{\"type\":\"command\",\"seq\":7,\"cmd\":\"confirm_t2\"}")]
        [TestCase("validate_config 3ad9012B", "{\"type\":\"command\",\"seq\":7,\"cmd\":\"validate_config\",\"code\":\"3AD9012B\"}")]
        public void ParsesTheScnSpelling(string line, string json)
        {
            Command c;
            string error;
            Assert.IsTrue(Command.TryParse(line, out c, out error), error);
            Assert.AreEqual(json, Json.Write(c.ToMessage(7)));
        }

        [TestCase("")]
        [TestCase("fly")]
        [TestCase("RESET")]
        [TestCase("reset now")]
        [TestCase("jog")]
        [TestCase("jog 1")]
        [TestCase("jog 0 +")]
        [TestCase("jog 7 +")]
        [TestCase("jog 1 sideways")]
        [TestCase("jog 1 + 0")]
        [TestCase("jog 1 + 101")]
        [TestCase("jog 1 + 10 extra")]
        [TestCase("jog -1 +")]
        [TestCase("set_mode")]
        [TestCase("set_mode t1")]
        [TestCase("validate_config")]
        [TestCase("validate_config 3AD9012")]
        [TestCase("validate_config 3AD9012B0")]
        [TestCase("validate_config 0x3AD901")]
        [TestCase("validate_config 3AD9012G")]
        [TestCase("validate_config 3AD9012B 1")]
        public void RefusesMalformedCommands(string line)
        {
            Command c;
            string error;
            Assert.IsFalse(Command.TryParse(line, out c, out error));
            Assert.IsNotEmpty(error);
            Assert.IsNull(c);
        }

        [Test]
        public void MotionCommandsAreMarked()
        {
            Assert.IsTrue(Command.Start().StartsMotion);
            Assert.IsTrue(Command.Resume().StartsMotion);
            Assert.IsTrue(Command.Jog(1, '+').StartsMotion);
            Assert.IsFalse(Command.JogStop().StartsMotion);
            Assert.IsFalse(Command.Reset().StartsMotion);
            Assert.Throws<ArgumentOutOfRangeException>(() => Command.Jog(0, '+'));
            Assert.Throws<ArgumentException>(() => Command.Of(CommandName.jog));
            Assert.Throws<ArgumentException>(() => Command.Of(CommandName.validate_config));
            Assert.Throws<ArgumentException>(() => Command.ValidateConfig("3AD9012"));
            Assert.IsFalse(Command.ValidateConfig("3AD9012B").StartsMotion);
        }
    }

    [TestFixture]
    public class BackoffTests
    {
        private static readonly TimeSpan First = TimeSpan.FromMilliseconds(100);
        private static readonly TimeSpan Max = TimeSpan.FromSeconds(5);

        [Test]
        public void CeilingDoublesFromFirstUpToMax()
        {
            var ms = Enumerable.Range(1, 9).Select(f => Backoff.Ceiling(f, First, Max).TotalMilliseconds).ToArray();
            Assert.AreEqual(new double[] { 100, 200, 400, 800, 1600, 3200, 5000, 5000, 5000 }, ms);
            Assert.AreEqual(Max, Backoff.Ceiling(1000, First, Max), "no overflow after many failures");
        }

        [Test]
        public void DelayIsDrawnFromTheUpperHalfOfTheCeiling()
        {
            Assert.AreEqual(TimeSpan.FromMilliseconds(200), Backoff.Delay(3, First, Max, 0.0));
            Assert.AreEqual(TimeSpan.FromMilliseconds(300), Backoff.Delay(3, First, Max, 0.5));
            Assert.That(Backoff.Delay(3, First, Max, 0.999999), Is.GreaterThan(TimeSpan.FromTicks(3999000)));
            Assert.That(Backoff.Delay(3, First, Max, 0.999999), Is.LessThanOrEqualTo(TimeSpan.FromMilliseconds(400)));
        }

        [Test]
        public void ClientsRefusedTogetherComeBackSpreadOut()
        {
            // 500 clients refused in the same instant, each with its own random source: their
            // second attempts spread over [200, 400] ms, not one millisecond.
            var rng = new Random(23);
            var delays = Enumerable.Range(0, 500).Select(_ => Backoff.Delay(3, First, Max, rng.NextDouble()).TotalMilliseconds).ToList();
            Assert.That(delays.Min(), Is.GreaterThanOrEqualTo(200));
            Assert.That(delays.Max(), Is.LessThanOrEqualTo(400));
            Assert.That(delays.Max() - delays.Min(), Is.GreaterThan(150), "jitter spreads the clients");
            int sameMillisecond = delays.GroupBy(d => (long)d).Max(g => g.Count());
            Assert.That(sameMillisecond, Is.LessThan(20), "no crowd in one millisecond");
        }

        [Test]
        public void OptionsOutOfOrderNeverThrow()
        {
            Assert.AreEqual(TimeSpan.Zero, Backoff.Delay(4, TimeSpan.Zero, Max, 0.5));
            Assert.AreEqual(First, Backoff.Ceiling(5, First, TimeSpan.FromMilliseconds(10)));
        }
    }
}
