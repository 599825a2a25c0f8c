// Typed server messages (protocol.md), read strictly from parsed JSON: a required field
// that is missing or of the wrong type, or a value that is not a known name, refuses the
// whole message (MessageException); a field this build does not know is reported
// (Unknown) but does not refuse the message, so a newer gateway that adds status fields
// still drives an older HMI, and the lead can see the gap in the Error event.
using System;
using System.Collections.Generic;
using System.Globalization;

namespace SafeState.Client
{
    public sealed class MessageException : Exception
    {
        public MessageException(string message) : base(message) { }
    }

    /// <summary>Reads typed fields from one JSON object and records which keys were read.</summary>
    internal sealed class Fields
    {
        private readonly JsonObject o;
        private readonly string what;
        private readonly HashSet<string> known = new HashSet<string>(StringComparer.Ordinal);

        public Fields(object value, string what)
        {
            o = value as JsonObject;
            this.what = what;
            if (o == null) throw new MessageException(what + " is not a JSON object");
        }

        public JsonObject Object { get { return o; } }

        public MessageException Bad(string key, string expected)
        {
            return new MessageException(what + ": \"" + key + "\" must be " + expected);
        }

        /// <summary>Keys present in the object that nobody asked for.</summary>
        public List<string> Unknown()
        {
            var u = new List<string>();
            foreach (string k in o.Keys)
            {
                if (!known.Contains(k)) u.Add(k);
            }
            return u;
        }

        public void Allow(params string[] keys)
        {
            foreach (string k in keys) known.Add(k);
        }

        private object Get(string key, bool required)
        {
            known.Add(key);
            if (!o.Has(key))
            {
                if (required) throw new MessageException(what + ": \"" + key + "\" is missing");
                return null;
            }
            return o[key];
        }

        public string Str(string key)
        {
            string s = StrOrNull(key, false);
            if (s == null) throw Bad(key, "a string");
            return s;
        }

        public string StrOrNull(string key, bool optional = false)
        {
            object v = Get(key, !optional);
            if (v == null) return null;
            var s = v as string;
            if (s == null) throw Bad(key, "a string or null");
            return s;
        }

        public long Int(string key)
        {
            object v = Get(key, true);
            if (!(v is long)) throw Bad(key, "an integer");
            return (long)v;
        }

        public long? IntOrNull(string key, bool optional = false)
        {
            object v = Get(key, !optional);
            if (v == null) return null;
            if (!(v is long)) throw Bad(key, "an integer or null");
            return (long)v;
        }

        public double Num(string key)
        {
            object v = Get(key, true);
            if (v is long) return (long)v;
            if (v is double) return (double)v;
            throw Bad(key, "a number");
        }

        public double? NumOrNull(string key, bool optional = false)
        {
            object v = Get(key, !optional);
            if (v == null) return null;
            if (v is long) return (long)v;
            if (v is double) return (double)v;
            throw Bad(key, "a number or null");
        }

        public bool? BoolOrNull(string key, bool optional = false)
        {
            object v = Get(key, !optional);
            if (v == null) return null;
            if (!(v is bool)) throw Bad(key, "true, false or null");
            return (bool)v;
        }

        public bool Bool(string key)
        {
            object v = Get(key, true);
            if (!(v is bool)) throw Bad(key, "true or false");
            return (bool)v;
        }

        public List<object> List(string key, bool optional = false)
        {
            object v = Get(key, !optional);
            if (v == null && optional) return null;
            var l = v as List<object>;
            if (l == null) throw Bad(key, "an array");
            return l;
        }

        public double[] Numbers(string key, int count)
        {
            List<object> l = List(key);
            if (l.Count != count) throw Bad(key, "an array of " + count + " numbers");
            var d = new double[count];
            for (int i = 0; i < count; ++i)
            {
                if (l[i] is long) d[i] = (long)l[i];
                else if (l[i] is double) d[i] = (double)l[i];
                else throw Bad(key, "an array of " + count + " numbers");
            }
            return d;
        }

        public JsonObject Obj(string key)
        {
            var j = Get(key, true) as JsonObject;
            if (j == null) throw Bad(key, "an object");
            return j;
        }

        public T Name<T>(string key) where T : struct
        {
            string s = Str(key);
            T v;
            if (!Wire.TryParse(s, out v)) throw Bad(key, "a " + typeof(T).Name + " name, not \"" + s + "\"");
            return v;
        }

        public T? NameOrNull<T>(string key, bool optional = false) where T : struct
        {
            string s = StrOrNull(key, optional);
            if (s == null) return null;
            T v;
            if (!Wire.TryParse(s, out v)) throw Bad(key, "a " + typeof(T).Name + " name or null, not \"" + s + "\"");
            return v;
        }

        /// <summary>One of a few fixed words, e.g. "open"/"closed": true for the second.</summary>
        public bool Either(string key, string no, string yes)
        {
            string s = Str(key);
            if (s == yes) return true;
            if (s == no) return false;
            throw Bad(key, "\"" + no + "\" or \"" + yes + "\"");
        }
    }

    /// <summary>The 50 Hz status snapshot (protocol.md `status`, also GET /api/status).</summary>
    public sealed class StatusMessage
    {
        public long T { get; private set; }
        public State State { get; private set; }
        public SubState? Sub { get; private set; }
        public Mode Mode { get; private set; }
        public StopCategory? Stop { get; private set; }
        public bool ContactorClosed { get; private set; }
        public bool DrivesEnabled { get; private set; }
        public bool BrakesReleased { get; private set; }
        public bool ResetLamp { get; private set; }
        public double TcpSpeed { get; private set; }
        /// <summary>Active alarms by name; a name this build does not know is kept as sent.</summary>
        public IReadOnlyList<string> Alarms { get; private set; }
        public double[] Joints { get; private set; }
        public double[] Tcp { get; private set; }
        public bool T2Confirmed { get; private set; }
        public Role? Owner { get; private set; }
        // Beyond protocol.md, sent by the gateway (SPEC §7: requested beside effective, first-out cause).
        public Mode? ModeRequested { get; private set; }
        public string Cause { get; private set; }
        public IReadOnlyList<AxisState> AxisStates { get; private set; }
        public long? GatewayPid { get; private set; }
        /// <summary>SPEC §10 (protocol.md `safety`): the active safety configuration's checksum,
        /// whether it is validated, reduced mode and recovery; null from a gateway without it.</summary>
        public SafetyStatus Safety { get; private set; }
        /// <summary>SPEC §11: the simulated person and what the simulated scanner and distance
        /// sensor see of it (docs/collaborative.md); null off the in-process simulated cell and
        /// from a gateway without it. Not what the core validated: that is Safety.</summary>
        public SimStatus Sim { get; private set; }
        /// <summary>The whole object as received, for fields this class does not type.</summary>
        public JsonObject Raw { get; private set; }

        // The gateway's extra fields this build knows (views.cpp status_json, protocol.md).
        private static readonly string[] Extras =
        {
            "target", "arming_step", "arming_progress", "program_index", "program_length", "simulated",
            "max_point_speed", "statusword", "core_heartbeat", "core_heartbeat_age_ms", "gateway_heartbeat",
            "core_pid", "gateway_restarts", "shutting_down",
        };

        internal static StatusMessage Read(Fields f, List<string> unknownNames)
        {
            var s = new StatusMessage();
            s.Raw = f.Object;
            s.T = f.Int("t");
            s.State = f.Name<State>("state");
            s.Sub = f.NameOrNull<SubState>("sub");
            s.Mode = f.Name<Mode>("mode");
            s.Stop = f.NameOrNull<StopCategory>("stop");
            s.ContactorClosed = f.Either("contactor", "open", "closed");
            s.DrivesEnabled = f.Either("drives", "disabled", "enabled");
            s.BrakesReleased = f.Either("brakes", "engaged", "released");
            s.ResetLamp = f.Either("reset_lamp", "off", "on");
            s.TcpSpeed = f.Num("tcp_speed");
            var alarms = new List<string>();
            foreach (object a in f.List("alarms"))
            {
                var name = a as string;
                if (name == null) throw f.Bad("alarms", "an array of alarm names");
                AlarmName known;
                if (!Wire.TryParse(name, out known)) unknownNames.Add("alarm " + name);
                alarms.Add(name);
            }
            s.Alarms = alarms;
            s.Joints = f.Numbers("joints", 6);
            s.Tcp = f.Numbers("tcp", 6);
            s.T2Confirmed = f.Bool("t2_confirmed");
            s.Owner = f.NameOrNull<Role>("owner");
            s.ModeRequested = f.NameOrNull<Mode>("mode_requested", true);
            s.Cause = f.StrOrNull("cause", true);
            s.GatewayPid = f.IntOrNull("gateway_pid", true);
            List<object> axes = f.List("axis_state", true);
            var states = new List<AxisState>();
            if (axes != null)
            {
                foreach (object a in axes)
                {
                    AxisState st;
                    if (!Wire.TryParse(a as string, out st)) throw f.Bad("axis_state", "an array of PLCopen axis states");
                    states.Add(st);
                }
            }
            s.AxisStates = states;
            if (f.Object.Has("safety")) s.Safety = SafetyStatus.Read(new Fields(f.Obj("safety"), "status.safety"));
            if (f.Object.Has("sim") && f.Object["sim"] != null) s.Sim = SimStatus.Read(new Fields(f.Obj("sim"), "status.sim"));
            f.Allow("sim");
            f.Allow(Extras);
            return s;
        }

        /// <summary>One line for a terminal: state, sub, mode, stop, speed, alarms.</summary>
        public string Line()
        {
            return string.Format(CultureInfo.InvariantCulture, "t={0} {1}{2} mode={3} stop={4} tcp={5:0.0}mm/s owner={6} alarms={7}",
                T, Wire.Name(State), Sub.HasValue ? "/" + Wire.Name(Sub.Value) : "", Wire.Name(Mode),
                Stop.HasValue ? Wire.Name(Stop.Value) : "-", TcpSpeed, Owner.HasValue ? Wire.Name(Owner.Value) : "none",
                Alarms.Count == 0 ? "-" : string.Join(",", Alarms));
        }
    }

    /// <summary>The status's `sim` object (SPEC §11, views.cpp status_sim_json): the person in
    /// the in-process simulated cell (null: nobody) and the simulated devices' fields.</summary>
    public sealed class SimStatus
    {
        public SimPerson Person { get; private set; }
        /// <summary>The simulated scanner's outer and inner field radii about the base axis, mm.</summary>
        public double OuterFieldMm { get; private set; }
        public double InnerFieldMm { get; private set; }
        /// <summary>Whether the person feeds the simulated scanner (the fields' OSSDs) and the
        /// distance sensor (separation_mm); a panel or scenario that sets those inputs itself turns
        /// them off.</summary>
        public bool Scanner { get; private set; }
        public bool DistanceSensor { get; private set; }

        internal static SimStatus Read(Fields f)
        {
            var s = new SimStatus();
            var pf = new Fields(f.Obj("person_fields"), "status.sim.person_fields");
            s.OuterFieldMm = NonNegative(pf, "outer_mm");
            s.InnerFieldMm = NonNegative(pf, "inner_mm");
            s.Scanner = pf.Bool("scanner");
            s.DistanceSensor = pf.Bool("distance_sensor");
            if (f.Object.Has("person") && f.Object["person"] != null)
            {
                s.Person = SimPerson.Read(new Fields(f.Obj("person"), "status.sim.person"));
            }
            else
            {
                f.StrOrNull("person");  // present and null: nobody in the cell
            }
            return s;
        }

        internal static double NonNegative(Fields f, string key)
        {
            double v = f.Num(key);
            if (!(v >= 0)) throw f.Bad(key, "a number >= 0");
            return v;
        }
    }

    /// <summary>The simulated person (SPEC §11): where it stands on the floor (mm, base frame),
    /// how fast it walks, which fields it is in and how far it is from the arm.</summary>
    public sealed class SimPerson
    {
        public double XMm { get; private set; }
        public double YMm { get; private set; }
        public double RadiusMm { get; private set; }
        public double SpeedMmS { get; private set; }
        public bool Walking { get; private set; }
        public bool InOuterField { get; private set; }
        public bool InInnerField { get; private set; }
        /// <summary>Distance from the person's body to the nearest point of the arm, mm.</summary>
        public double SeparationMm { get; private set; }
        /// <summary>That point: 0..6 a DH frame origin, 7 the TCP.</summary>
        public int NearestPoint { get; private set; }

        internal static SimPerson Read(Fields f)
        {
            var p = new SimPerson();
            p.XMm = f.Num("x_mm");
            p.YMm = f.Num("y_mm");
            p.RadiusMm = SimStatus.NonNegative(f, "radius_mm");
            p.SpeedMmS = SimStatus.NonNegative(f, "speed_mm_s");
            p.Walking = f.Bool("walking");
            p.InOuterField = f.Bool("in_outer");
            p.InInnerField = f.Bool("in_inner");
            p.SeparationMm = SimStatus.NonNegative(f, "separation_mm");
            long n = f.Int("nearest_point");
            if (n < 0 || n > 7) throw f.Bad("nearest_point", "an integer 0..7");
            p.NearestPoint = (int)n;
            return p;
        }
    }

    /// <summary>The status message's `safety` object (protocol.md, SPEC §10, §11).</summary>
    public sealed class SafetyStatus
    {
        /// <summary>The active configuration's checksum, 8 upper-case hex digits.</summary>
        public string Checksum { get; private set; }
        /// <summary>The operator has confirmed this checksum (validate_config), or it is the built-in one.</summary>
        public bool Validated { get; private set; }
        public bool Reduced { get; private set; }
        /// <summary>Why reduced mode is active: "zone", "input", "field".</summary>
        public IReadOnlyList<string> ReducedBy { get; private set; }
        public bool Recovery { get; private set; }
        /// <summary>The TCP speed limit in force, mm/s.</summary>
        public double SpeedLimit { get; private set; }

        // SPEC §11 collaborative operation (protocol.md's v_allowed, fields, separation_mm; the
        // gateway's pfl, contact_force, contact_force_limit, pfl_speed_limit). Each is optional:
        // a gateway that predates it leaves it out (null, false).

        /// <summary>The TCP speed speed and separation monitoring allows now, mm/s (0: the robot
        /// holds); null while SSM does not act (collaborative and ssm on, mode AUTO).</summary>
        public double? VAllowed { get; private set; }
        /// <summary>The outer protective field (slows: reduced mode) is interrupted, as the core
        /// validated it; null from a gateway that does not report the fields.</summary>
        public bool? OuterFieldInterrupted { get; private set; }
        /// <summary>The inner protective field (stops: rule 9, PERSON_IN_FIELD) is interrupted;
        /// null from a gateway that does not report the fields.</summary>
        public bool? InnerFieldInterrupted { get; private set; }
        /// <summary>The separation SSM uses, mm; null while SSM does not act.</summary>
        public double? SeparationMm { get; private set; }
        /// <summary>Power and force limiting and collision detection act (collaborative and pfl on).</summary>
        public bool Pfl { get; private set; }
        /// <summary>The force at the TCP the core estimates from the drives' torques, N; null while pfl is off.</summary>
        public double? ContactForce { get; private set; }
        /// <summary>The body region's quasi-static limit F_qs, N (above it: COLLISION); null without pfl.</summary>
        public double? ContactForceLimit { get; private set; }
        /// <summary>The PFL speed cap v_pfl, mm/s (while the outer field is interrupted); null without pfl.</summary>
        public double? PflSpeedLimit { get; private set; }

        /// <summary>SPEC §12 (protocol.md `brake_test`): when the brake test is due, the latest
        /// result, the test in progress; null from a gateway that predates it.</summary>
        public BrakeTestStatus BrakeTest { get; private set; }

        internal static SafetyStatus Read(Fields f)
        {
            var s = new SafetyStatus();
            s.Checksum = f.Str("checksum");
            if (s.Checksum.Length != 8) throw f.Bad("checksum", "8 hex digits");
            foreach (char c in s.Checksum)
            {
                if (!Uri.IsHexDigit(c)) throw f.Bad("checksum", "8 hex digits");
            }
            s.Validated = f.Bool("validated");
            s.Reduced = f.Bool("reduced");
            var by = new List<string>();
            foreach (object o in f.List("reduced_by"))
            {
                var w = o as string;
                if (w == null) throw f.Bad("reduced_by", "an array of strings");
                by.Add(w);
            }
            s.ReducedBy = by;
            s.Recovery = f.Bool("recovery");
            s.SpeedLimit = f.Num("speed_limit");
            s.VAllowed = f.NumOrNull("v_allowed", true);
            if (f.Object.Has("fields"))
            {
                var fields = new Fields(f.Obj("fields"), "status.safety.fields");
                s.OuterFieldInterrupted = fields.Either("outer", "clear", "interrupted");
                s.InnerFieldInterrupted = fields.Either("inner", "clear", "interrupted");
            }
            s.SeparationMm = f.NumOrNull("separation_mm", true);
            s.Pfl = f.BoolOrNull("pfl", true) ?? false;
            s.ContactForce = f.NumOrNull("contact_force", true);
            s.ContactForceLimit = f.NumOrNull("contact_force_limit", true);
            s.PflSpeedLimit = f.NumOrNull("pfl_speed_limit", true);
            if (s.VAllowed < 0) throw f.Bad("v_allowed", "a number >= 0 or null");
            if (s.SeparationMm < 0) throw f.Bad("separation_mm", "a number >= 0 or null");
            if (s.ContactForce < 0) throw f.Bad("contact_force", "a number >= 0 or null");
            if (f.Object.Has("brake_test"))
            {
                s.BrakeTest = BrakeTestStatus.Read(new Fields(f.Obj("brake_test"), "status.safety.brake_test"));
            }
            return s;
        }
    }

    /// <summary>The status's `safety.brake_test` object (SPEC §12): protocol.md's due_in_h and
    /// last, then the gateway's running, axis, progress, due, required and the latest result on
    /// record (last_time, last_axis, drift_deg), each optional (a gateway that predates it leaves
    /// it out: null, false).</summary>
    public sealed class BrakeTestStatus
    {
        /// <summary>Hours until the test is due, negative when overdue; null when no pass is on
        /// record or the configuration requires none.</summary>
        public double? DueInHours { get; private set; }
        /// <summary>The latest result on record: "none", "passed" or "failed".</summary>
        public string Last { get; private set; }
        /// <summary>The test runs (sub-state BRAKE_TEST).</summary>
        public bool Running { get; private set; }
        /// <summary>The axis under test, 1..6; null while none runs.</summary>
        public int? Axis { get; private set; }
        /// <summary>Percent of the whole test done (4 steps per axis); null while none runs.</summary>
        public int? Progress { get; private set; }
        /// <summary>BRAKE_TEST_DUE: the last pass is older than interval_h (or none passed).</summary>
        public bool Due { get; private set; }
        /// <summary>servo_on in AUTO is refused (BRAKE_TEST_REQUIRED) until a test passes.</summary>
        public bool Required { get; private set; }
        /// <summary>When the latest result was logged (ISO-8601 UTC); null when none is on record.</summary>
        public string LastTime { get; private set; }
        /// <summary>The axis that slipped in the latest result; null on a pass or when none.</summary>
        public int? LastAxis { get; private set; }
        /// <summary>Every axis' drift in the latest result, degrees (6 values); null when none.</summary>
        public double[] DriftDeg { get; private set; }

        private static readonly string[] Results = { "none", "passed", "failed" };

        internal static BrakeTestStatus Read(Fields f)
        {
            var s = new BrakeTestStatus();
            s.DueInHours = f.NumOrNull("due_in_h");
            s.Last = f.Str("last");
            if (Array.IndexOf(Results, s.Last) < 0) throw f.Bad("last", "\"none\", \"passed\" or \"failed\"");
            s.Running = f.BoolOrNull("running", true) ?? false;
            s.Axis = AxisOrNull(f, "axis");
            long? progress = f.IntOrNull("progress", true);
            if (progress < 0 || progress > 100) throw f.Bad("progress", "an integer 0..100 or null");
            s.Progress = (int?)progress;
            s.Due = f.BoolOrNull("due", true) ?? false;
            s.Required = f.BoolOrNull("required", true) ?? false;
            s.LastTime = f.StrOrNull("last_time", true);
            s.LastAxis = AxisOrNull(f, "last_axis");
            if (f.List("drift_deg", true) != null)
            {
                s.DriftDeg = f.Numbers("drift_deg", 6);
                foreach (double d in s.DriftDeg)
                {
                    if (!(d >= 0)) throw f.Bad("drift_deg", "an array of 6 numbers >= 0 or null");
                }
            }
            return s;
        }

        private static int? AxisOrNull(Fields f, string key)
        {
            long? a = f.IntOrNull(key, true);
            if (a < 1 || a > 6) throw f.Bad(key, "an axis 1..6 or null");
            return (int?)a;
        }

        /// <summary>One line: "due in 5.2 h, last passed" / "running axis 3 (45 %)" / "last failed axis 3".</summary>
        public string Line()
        {
            if (Running) return string.Format(CultureInfo.InvariantCulture, "running axis {0} ({1} %)", Axis, Progress);
            string due = DueInHours.HasValue
                ? string.Format(CultureInfo.InvariantCulture, DueInHours.Value < 0 ? "overdue by {0:0.0} h" : "due in {0:0.0} h", Math.Abs(DueInHours.Value))
                : "not due";
            return due + ", last " + Last + (LastAxis.HasValue ? " axis " + LastAxis.Value : "");
        }
    }

    public enum EventKind
    {
        transition,
        alarm,
        alarm_cleared,
        command,
        /// <summary>SPEC §10: the operator confirmed a safety configuration (data: checksum, client, role).</summary>
        config_validated,
        /// <summary>SPEC §12: a brake test's result.</summary>
        brake_test,
    }

    /// <summary>One event of the log (protocol.md `event`, also an item of GET /api/events).</summary>
    public sealed class EventMessage
    {
        public long? Id { get; private set; }
        public long T { get; private set; }
        public string Time { get; private set; }
        public EventKind Kind { get; private set; }
        public JsonObject Data { get; private set; }
        /// <summary>/api/events only: where the stop's black box is served
        /// (/api/events/ID/blackbox), or null; HistoryClient.GetBlackBoxAsync reads it.</summary>
        public string BlackBoxUrl { get; private set; }

        // Typed views of Data; null when the kind has no such field.
        public string From { get { return Data["from"] as string; } }
        public string To { get { return Data["to"] as string; } }
        public string Cmd { get { return Data["cmd"] as string; } }
        public string Name { get { return Data["name"] as string; } }
        public Result? Result
        {
            get
            {
                Result r;
                return Wire.TryParse(Data["result"] as string, out r) ? r : (Result?)null;
            }
        }

        internal static EventMessage Read(Fields f, bool fromHistory)
        {
            var e = new EventMessage();
            e.Id = f.IntOrNull("id");
            e.T = f.Int("t");
            e.Time = f.Str("time");
            e.Kind = f.Name<EventKind>("kind");
            e.Data = f.Obj("data");
            if (fromHistory)
            {
                // protocol.md "History": a stop's black box is served on its own; the row
                // carries its address (/api/events/ID/blackbox) or null.
                object bb = f.Object["blackbox"];
                f.Allow("blackbox");
                if (bb != null && !(bb is string)) throw f.Bad("blackbox", "a URL string or null");
                e.BlackBoxUrl = bb as string;
            }
            return e;
        }

        public string Line()
        {
            string what;
            switch (Kind)
            {
                case EventKind.transition: what = From + " -> " + To; break;
                case EventKind.command: what = Cmd + " from " + (Data["from"] as string) + ": " + (Data["result"] as string); break;
                case EventKind.config_validated: what = "safety configuration " + (Data["checksum"] as string) + " validated by " + (Data["client"] as string); break;
                default: what = Name; break;
            }
            return string.Format(CultureInfo.InvariantCulture, "#{0} {1} {2} {3}", Id, Time, Kind, what);
        }
    }

    /// <summary>An active alarm (GET /api/alarms).</summary>
    public sealed class AlarmEntry
    {
        public string Name { get; private set; }
        public AlarmName? Known { get; private set; }
        public long Number { get; private set; }
        public Severity Severity { get; private set; }
        public string Text { get; private set; }
        public string Remedy { get; private set; }
        public string Detail { get; private set; }
        /// <summary>What the alarm names, as the scenario format's alarm.NAME.detail= does: axis.N,
        /// tcp, a zone's name, estop.a, ...; null from a gateway without it.</summary>
        public string Subject { get; private set; }
        public long Since { get; private set; }

        internal static AlarmEntry Read(Fields f)
        {
            var a = new AlarmEntry();
            a.Name = f.Str("name");
            AlarmName n;
            if (Wire.TryParse(a.Name, out n)) a.Known = n;
            a.Number = f.Int("number");
            a.Severity = f.Name<Severity>("severity");
            a.Text = f.Str("text");
            a.Remedy = f.Str("remedy");
            a.Detail = f.StrOrNull("detail", true);
            a.Subject = f.StrOrNull("subject", true);
            a.Since = f.Int("since");
            return a;
        }

        public string Line()
        {
            return string.Format(CultureInfo.InvariantCulture, "{0} ({1}, {2}) since t={3}{4}: {5} Remedy: {6}", Name, Number,
                Wire.Name(Severity), Since, string.IsNullOrEmpty(Detail) ? "" : " [" + Detail + "]", Text, Remedy);
        }
    }

    public enum ClientErrorKind
    {
        /// <summary>A frame that is not valid JSON (or not valid UTF-8).</summary>
        BadJson,
        /// <summary>Valid JSON that is not a valid message: missing or mistyped field, unknown type or name.</summary>
        BadMessage,
        /// <summary>A field or name this build does not know; the message was still used.</summary>
        UnknownField,
        /// <summary>A frame over ClientOptions.MaxFrameBytes; discarded unread.</summary>
        TooLarge,
        /// <summary>A binary frame; the protocol has only text frames.</summary>
        BinaryFrame,
        /// <summary>An `error` message from the server (Code says which).</summary>
        ServerError,
        /// <summary>A reply whose seq no pending command has (late, or never sent).</summary>
        UnexpectedReply,
        /// <summary>The connection was lost; pending commands failed, motion helpers stopped.</summary>
        Disconnected,
        /// <summary>One reconnect attempt failed; the client keeps trying with back-off.</summary>
        ReconnectFailed,
        /// <summary>An event handler of the application threw; the client carried on.</summary>
        HandlerFailed,
        /// <summary>A jog hold stopped on its own (refused, timed out, or the link was lost).</summary>
        JogStopped,
    }

    /// <summary>What the Error event carries: never an exception thrown at the caller.</summary>
    public sealed class ClientError : EventArgs
    {
        public ClientError(ClientErrorKind kind, string message, string serverCode = null)
        {
            Kind = kind;
            Message = message;
            ServerCode = serverCode;
        }

        public ClientErrorKind Kind { get; private set; }
        public string Message { get; private set; }
        /// <summary>For ServerError: the protocol.md error code as sent.</summary>
        public string ServerCode { get; private set; }

        public override string ToString() { return Kind + (ServerCode != null ? " " + ServerCode : "") + ": " + Message; }
    }

    /// <summary>Why a command's task failed without a reply (it never hangs).</summary>
    public enum CommandFailure
    {
        NotConnected,
        Timeout,
        Disconnected,
        BadReply,
        Refused,
        Closed,
    }

    public sealed class CommandFailedException : Exception
    {
        public CommandFailedException(CommandFailure reason, string message) : base(message) { Reason = reason; }
        public CommandFailure Reason { get; private set; }
    }
}
