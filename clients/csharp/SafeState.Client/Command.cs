// A command of SPEC.md §4, built in code or parsed from the .scn spelling
// (spec/scenario-format.md `cmd`): "reset", "jog 1 + 10", "set_mode T1".
using System;
using System.Collections.Generic;
using System.Globalization;

namespace SafeState.Client
{
    public sealed class Command
    {
        private Command(CommandName name) { Name = name; }

        public CommandName Name { get; private set; }
        /// <summary>jog: axis 1..6.</summary>
        public int Axis { get; private set; }
        /// <summary>jog: '+' or '-'.</summary>
        public char Dir { get; private set; }
        /// <summary>jog: percent 1..100.</summary>
        public int Speed { get; private set; }
        /// <summary>set_mode: the mode asked for (always refused: MODE_BY_SELECTOR_ONLY).</summary>
        public Mode Mode { get; private set; }
        /// <summary>validate_config: the checksum the operator read, 8 hex digits (SPEC §10).</summary>
        public string Code { get; private set; }

        /// <summary>Commands that start motion. They are never re-sent by the client:
        /// after a lost link the operator must ask again (ISO 10218-1: no unexpected start-up).</summary>
        public bool StartsMotion
        {
            get { return Name == CommandName.start || Name == CommandName.resume || Name == CommandName.jog; }
        }

        public static Command Of(CommandName name)
        {
            if (name == CommandName.jog || name == CommandName.set_mode || name == CommandName.validate_config)
            {
                throw new ArgumentException(Wire.Name(name) + " takes arguments: use Command.Jog, Command.SetMode or Command.ValidateConfig");
            }
            return new Command(name);
        }

        public static Command Reset() { return Of(CommandName.reset); }
        public static Command ServoOn() { return Of(CommandName.servo_on); }
        public static Command ServoOff() { return Of(CommandName.servo_off); }
        public static Command Start() { return Of(CommandName.start); }
        public static Command Pause() { return Of(CommandName.pause); }
        public static Command Resume() { return Of(CommandName.resume); }
        public static Command Stop() { return Of(CommandName.stop); }
        public static Command JogStop() { return Of(CommandName.jog_stop); }
        public static Command ConfirmT2() { return Of(CommandName.confirm_t2); }

        public static Command Jog(int axis, char dir, int speed = 10)
        {
            if (axis < 1 || axis > 6) throw new ArgumentOutOfRangeException("axis", axis, "jog axis is 1..6");
            if (dir != '+' && dir != '-') throw new ArgumentOutOfRangeException("dir", dir, "jog direction is '+' or '-'");
            if (speed < 1 || speed > 100) throw new ArgumentOutOfRangeException("speed", speed, "jog speed is 1..100 %");
            return new Command(CommandName.jog) { Axis = axis, Dir = dir, Speed = speed };
        }

        public static Command SetMode(Mode mode) { return new Command(CommandName.set_mode) { Mode = mode }; }

        /// <summary>SPEC §10: confirm the active safety configuration by its checksum (pendant, T1/T2, IDLE).</summary>
        public static Command ValidateConfig(string code)
        {
            if (!IsChecksum(code)) throw new ArgumentException("validate_config takes the checksum: 8 hex digits", "code");
            return new Command(CommandName.validate_config) { Code = code.ToUpperInvariant() };
        }

        private static bool IsChecksum(string code)
        {
            if (code == null || code.Length != 8) return false;
            foreach (char c in code)
            {
                if (!Uri.IsHexDigit(c)) return false;
            }
            return true;
        }

        /// <summary>Parses the .scn spelling; false with a reason when the line is not a command.</summary>
        public static bool TryParse(string line, out Command command, out string error)
        {
            command = null;
            error = null;
            string[] w = (line ?? "").Split(new[] { ' ', '\t' }, StringSplitOptions.RemoveEmptyEntries);
            CommandName name;
            if (w.Length == 0) { error = "empty command"; return false; }
            if (!Wire.TryParse(w[0], out name))
            {
                error = "unknown command \"" + w[0] + "\" (expected one of " + string.Join(", ", Wire.Names<CommandName>()) + ")";
                return false;
            }
            if (name == CommandName.jog) return ParseJog(w, out command, out error);
            if (name == CommandName.set_mode)
            {
                Mode m;
                if (w.Length != 2 || !Wire.TryParse(w[1], out m)) { error = "set_mode takes one mode: AUTO, T1, T2 or NONE"; return false; }
                command = SetMode(m);
                return true;
            }
            if (name == CommandName.validate_config)
            {
                if (w.Length != 2 || !IsChecksum(w[1])) { error = "validate_config takes the checksum: 8 hex digits"; return false; }
                command = ValidateConfig(w[1]);
                return true;
            }
            if (w.Length != 1) { error = w[0] + " takes no arguments"; return false; }
            command = Of(name);
            return true;
        }

        private static bool ParseJog(string[] w, out Command command, out string error)
        {
            command = null;
            error = "jog takes AXIS DIR [SPEED]: axis 1..6, dir + or -, speed 1..100 (default 10)";
            int axis, speed = 10;
            if (w.Length < 3 || w.Length > 4) return false;
            if (!int.TryParse(w[1], NumberStyles.None, CultureInfo.InvariantCulture, out axis) || axis < 1 || axis > 6) return false;
            if (w[2] != "+" && w[2] != "-") return false;
            if (w.Length == 4 && (!int.TryParse(w[3], NumberStyles.None, CultureInfo.InvariantCulture, out speed) || speed < 1 || speed > 100))
            {
                return false;
            }
            command = Jog(axis, w[2][0], speed);
            error = null;
            return true;
        }

        /// <summary>The protocol.md message for this command with the given seq.</summary>
        public JsonObject ToMessage(long seq)
        {
            var o = new JsonObject().Set("type", "command").Set("seq", seq).Set("cmd", Wire.Name(Name));
            if (Name == CommandName.jog)
            {
                o.Set("axis", Axis).Set("dir", Dir.ToString()).Set("speed", Speed);
            }
            else if (Name == CommandName.set_mode)
            {
                o.Set("mode", Wire.Name(Mode));
            }
            else if (Name == CommandName.validate_config)
            {
                o.Set("code", Code);
            }
            return o;
        }

        public override string ToString()
        {
            if (Name == CommandName.jog) return string.Format(CultureInfo.InvariantCulture, "jog {0} {1} {2}", Axis, Dir, Speed);
            if (Name == CommandName.set_mode) return "set_mode " + Wire.Name(Mode);
            if (Name == CommandName.validate_config) return "validate_config " + Code;
            return Wire.Name(Name);
        }
    }
}
