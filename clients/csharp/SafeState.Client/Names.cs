// The hand-written half of the names: the generated enums (Generated/Names.g.cs) list the
// wire names in the core's order; these helpers map both ways, exactly and case-sensitively
// (Enum.Parse would also accept "3" or "idle", which the server never sends).
using System;
using System.Collections.Generic;

namespace SafeState.Client
{
    /// <summary>How long an alarm stays active (SPEC.md §7, "active").</summary>
    public enum AlarmLatch
    {
        PowerCycle,
        Reset,
        Condition,
        UntilOk,
    }

    /// <summary>One row of the core's alarm table.</summary>
    public sealed class AlarmInfo
    {
        public AlarmInfo(AlarmName name, int number, Severity severity, AlarmLatch latch, string text, string remedy)
        {
            Name = name;
            Number = number;
            Severity = severity;
            Latch = latch;
            Text = text;
            Remedy = remedy;
        }

        public AlarmName Name { get; private set; }
        public int Number { get; private set; }
        public Severity Severity { get; private set; }
        public AlarmLatch Latch { get; private set; }
        public string Text { get; private set; }
        public string Remedy { get; private set; }
    }

    public static partial class Alarms
    {
        /// <summary>The table row of an alarm.</summary>
        public static AlarmInfo Info(AlarmName name)
        {
            foreach (AlarmInfo a in Table)
            {
                if (a.Name == name) return a;
            }
            throw new ArgumentOutOfRangeException("name", name, "not an alarm of this build");
        }
    }

    /// <summary>Wire spelling of the SPEC.md names, both ways.</summary>
    public static partial class Wire
    {
        // Built on first use: the name arrays live in the other half of this partial class,
        // and C# does not order static initialisers across files.
        private static Dictionary<Type, string[]> tables;

        private static Dictionary<Type, string[]> BuildTables()
        {
            return new Dictionary<Type, string[]>
        {
            { typeof(State), StateNames },
            { typeof(SubState), SubStateNames },
            { typeof(Mode), ModeNames },
            { typeof(StopCategory), StopCategoryNames },
            { typeof(Result), ResultNames },
            { typeof(CommandName), CommandNameNames },
            { typeof(Source), SourceNames },
            { typeof(Role), RoleNames },
            { typeof(Severity), SeverityNames },
            { typeof(AxisState), AxisStateNames },
            { typeof(Cia402State), Cia402StateNames },
            { typeof(ArmingStep), ArmingStepNames },
            { typeof(ErrorCode), ErrorCodeNames },
            { typeof(EventKind), EventKindNames },
        };
        }

        // protocol.md event kinds (the gateway's, not a core table).
        internal static readonly string[] EventKindNames = { "transition", "alarm", "alarm_cleared", "command", "config_validated", "brake_test" };

        /// <summary>The wire name of a value, e.g. Result.NOT_CONTROL_OWNER -> "NOT_CONTROL_OWNER".</summary>
        public static string Name<T>(T value) where T : struct
        {
            if (typeof(T) == typeof(AlarmName)) return value.ToString();
            string[] names = Table(typeof(T));
            int i = Convert.ToInt32(value);
            if (i < 0 || i >= names.Length) throw new ArgumentOutOfRangeException("value");
            return names[i];
        }

        /// <summary>Exact, case-sensitive lookup of a wire name.</summary>
        public static bool TryParse<T>(string name, out T value) where T : struct
        {
            value = default(T);
            if (name == null) return false;
            if (typeof(T) == typeof(AlarmName))
            {
                if (Array.IndexOf(AlarmNameNames, name) < 0) return false;
                value = (T)Enum.Parse(typeof(AlarmName), name);
                return true;
            }
            int i = Array.IndexOf(Table(typeof(T)), name);
            if (i < 0) return false;
            value = (T)Enum.ToObject(typeof(T), i);
            return true;
        }

        /// <summary>Every wire name of an enum, in the core's order.</summary>
        public static IReadOnlyList<string> Names<T>() where T : struct
        {
            return typeof(T) == typeof(AlarmName) ? AlarmNameNames : Table(typeof(T));
        }

        private static string[] Table(Type t)
        {
            string[] names;
            if (tables == null) tables = BuildTables();
            if (!tables.TryGetValue(t, out names)) throw new ArgumentException(t.Name + " is not a SafeState name");
            return names;
        }
    }
}
