// A small strict JSON reader and writer (RFC 8259), so the library needs no NuGet package
// and decides itself what counts as bad server input: trailing garbage, duplicate keys,
// lone surrogates, control characters in strings, leading zeros, NaN and nesting deeper
// than MaxDepth are all refused with a JsonException naming the offset.
using System;
using System.Collections.Generic;
using System.Globalization;
using System.Text;

namespace SafeState.Client
{
    public sealed class JsonException : Exception
    {
        public JsonException(string message) : base(message) { }
    }

    /// <summary>A JSON object: keys in the order received, no duplicates.</summary>
    public sealed class JsonObject
    {
        private readonly Dictionary<string, object> values = new Dictionary<string, object>(StringComparer.Ordinal);
        private readonly List<string> keys = new List<string>();

        public IReadOnlyList<string> Keys { get { return keys; } }
        public int Count { get { return keys.Count; } }
        public bool Has(string key) { return values.ContainsKey(key); }

        public object this[string key]
        {
            get { object v; return values.TryGetValue(key, out v) ? v : null; }
        }

        internal bool TryAdd(string key, object value)
        {
            if (values.ContainsKey(key)) return false;
            values.Add(key, value);
            keys.Add(key);
            return true;
        }

        public JsonObject Set(string key, object value)
        {
            if (!values.ContainsKey(key)) keys.Add(key);
            values[key] = value;
            return this;
        }
    }

    public static class Json
    {
        public const int MaxDepth = 32;

        /// <summary>Parses one JSON text. Numbers are long when integral and in range, else double.</summary>
        public static object Parse(string text)
        {
            if (text == null) throw new JsonException("no text");
            var r = new Reader(text);
            r.SkipSpace();
            object v = r.Value(0);
            r.SkipSpace();
            if (r.Pos != text.Length) throw r.Fail("unexpected text after the value");
            return v;
        }

        public static string Write(object value)
        {
            var sb = new StringBuilder();
            WriteTo(sb, value);
            return sb.ToString();
        }

        private static void WriteTo(StringBuilder sb, object v)
        {
            if (v == null) { sb.Append("null"); return; }
            var s = v as string;
            if (s != null) { WriteString(sb, s); return; }
            if (v is bool) { sb.Append((bool)v ? "true" : "false"); return; }
            if (v is int || v is long || v is uint || v is byte)
            {
                sb.Append(Convert.ToInt64(v, CultureInfo.InvariantCulture).ToString(CultureInfo.InvariantCulture));
                return;
            }
            if (v is double || v is float)
            {
                double d = Convert.ToDouble(v, CultureInfo.InvariantCulture);
                if (double.IsNaN(d) || double.IsInfinity(d)) throw new JsonException("NaN and infinity are not JSON");
                sb.Append(d.ToString("R", CultureInfo.InvariantCulture));
                return;
            }
            var o = v as JsonObject;
            if (o != null)
            {
                sb.Append('{');
                for (int i = 0; i < o.Keys.Count; ++i)
                {
                    if (i > 0) sb.Append(',');
                    WriteString(sb, o.Keys[i]);
                    sb.Append(':');
                    WriteTo(sb, o[o.Keys[i]]);
                }
                sb.Append('}');
                return;
            }
            var list = v as System.Collections.IEnumerable;
            if (list != null)
            {
                sb.Append('[');
                bool first = true;
                foreach (object x in list)
                {
                    if (!first) sb.Append(',');
                    first = false;
                    WriteTo(sb, x);
                }
                sb.Append(']');
                return;
            }
            throw new JsonException("cannot write a " + v.GetType().Name + " as JSON");
        }

        private static void WriteString(StringBuilder sb, string s)
        {
            sb.Append('"');
            foreach (char c in s)
            {
                switch (c)
                {
                    case '"': sb.Append("\\\""); break;
                    case '\\': sb.Append("\\\\"); break;
                    case '\n': sb.Append("\\n"); break;
                    case '\r': sb.Append("\\r"); break;
                    case '\t': sb.Append("\\t"); break;
                    default:
                        if (c < 0x20) sb.Append("\\u").Append(((int)c).ToString("x4", CultureInfo.InvariantCulture));
                        else sb.Append(c);
                        break;
                }
            }
            sb.Append('"');
        }

        private sealed class Reader
        {
            private readonly string s;
            public int Pos;

            public Reader(string text) { s = text; }

            public JsonException Fail(string what)
            {
                return new JsonException("invalid JSON at offset " + Pos + ": " + what);
            }

            public void SkipSpace()
            {
                while (Pos < s.Length && (s[Pos] == ' ' || s[Pos] == '\t' || s[Pos] == '\n' || s[Pos] == '\r')) ++Pos;
            }

            public object Value(int depth)
            {
                if (depth > MaxDepth) throw Fail("nested deeper than " + MaxDepth);
                if (Pos >= s.Length) throw Fail("unexpected end");
                char c = s[Pos];
                switch (c)
                {
                    case '{': return Object(depth);
                    case '[': return Array(depth);
                    case '"': return String();
                    case 't': Literal("true"); return true;
                    case 'f': Literal("false"); return false;
                    case 'n': Literal("null"); return null;
                    default:
                        if (c == '-' || (c >= '0' && c <= '9')) return Number();
                        throw Fail("unexpected character '" + c + "'");
                }
            }

            private void Literal(string word)
            {
                if (string.CompareOrdinal(s, Pos, word, 0, word.Length) != 0) throw Fail("expected " + word);
                Pos += word.Length;
            }

            private JsonObject Object(int depth)
            {
                var o = new JsonObject();
                ++Pos;
                SkipSpace();
                if (Pos < s.Length && s[Pos] == '}') { ++Pos; return o; }
                while (true)
                {
                    SkipSpace();
                    if (Pos >= s.Length || s[Pos] != '"') throw Fail("expected a key");
                    int at = Pos;
                    string key = String();
                    SkipSpace();
                    Expect(':');
                    SkipSpace();
                    object v = Value(depth + 1);
                    if (!o.TryAdd(key, v)) { Pos = at; throw Fail("duplicate key \"" + key + "\""); }
                    SkipSpace();
                    if (Pos < s.Length && s[Pos] == ',') { ++Pos; continue; }
                    Expect('}');
                    return o;
                }
            }

            private List<object> Array(int depth)
            {
                var a = new List<object>();
                ++Pos;
                SkipSpace();
                if (Pos < s.Length && s[Pos] == ']') { ++Pos; return a; }
                while (true)
                {
                    SkipSpace();
                    a.Add(Value(depth + 1));
                    SkipSpace();
                    if (Pos < s.Length && s[Pos] == ',') { ++Pos; continue; }
                    Expect(']');
                    return a;
                }
            }

            private void Expect(char c)
            {
                if (Pos >= s.Length || s[Pos] != c) throw Fail("expected '" + c + "'");
                ++Pos;
            }

            private string String()
            {
                ++Pos;
                var sb = new StringBuilder();
                while (true)
                {
                    if (Pos >= s.Length) throw Fail("unterminated string");
                    char c = s[Pos++];
                    if (c == '"') return sb.ToString();
                    if (c < 0x20) { --Pos; throw Fail("control character in a string"); }
                    if (char.IsSurrogate(c))
                    {
                        if (!char.IsHighSurrogate(c) || Pos >= s.Length || !char.IsLowSurrogate(s[Pos]))
                        {
                            --Pos;
                            throw Fail("lone surrogate");
                        }
                        sb.Append(c).Append(s[Pos++]);
                        continue;
                    }
                    if (c != '\\') { sb.Append(c); continue; }
                    Escape(sb);
                }
            }

            private void Escape(StringBuilder sb)
            {
                if (Pos >= s.Length) throw Fail("unterminated escape");
                char e = s[Pos++];
                switch (e)
                {
                    case '"': sb.Append('"'); return;
                    case '\\': sb.Append('\\'); return;
                    case '/': sb.Append('/'); return;
                    case 'b': sb.Append('\b'); return;
                    case 'f': sb.Append('\f'); return;
                    case 'n': sb.Append('\n'); return;
                    case 'r': sb.Append('\r'); return;
                    case 't': sb.Append('\t'); return;
                    case 'u': break;
                    default: --Pos; throw Fail("bad escape '\\" + e + "'");
                }
                char u = Hex4();
                if (char.IsHighSurrogate(u))
                {
                    if (Pos + 1 < s.Length && s[Pos] == '\\' && s[Pos + 1] == 'u')
                    {
                        Pos += 2;
                        char low = Hex4();
                        if (!char.IsLowSurrogate(low)) throw Fail("lone surrogate");
                        sb.Append(u).Append(low);
                        return;
                    }
                    throw Fail("lone surrogate");
                }
                if (char.IsLowSurrogate(u)) throw Fail("lone surrogate");
                sb.Append(u);
            }

            private char Hex4()
            {
                if (Pos + 4 > s.Length) throw Fail("short \\u escape");
                int v = 0;
                for (int i = 0; i < 4; ++i)
                {
                    char h = s[Pos++];
                    int d = (h >= '0' && h <= '9') ? h - '0' : (h >= 'a' && h <= 'f') ? h - 'a' + 10
                          : (h >= 'A' && h <= 'F') ? h - 'A' + 10 : -1;
                    if (d < 0) { --Pos; throw Fail("bad hex digit"); }
                    v = v * 16 + d;
                }
                return (char)v;
            }

            private object Number()
            {
                int start = Pos;
                if (s[Pos] == '-') ++Pos;
                if (Pos >= s.Length) throw Fail("bad number");
                if (s[Pos] == '0') ++Pos;
                else if (s[Pos] >= '1' && s[Pos] <= '9') Digits();
                else throw Fail("bad number");
                bool integral = true;
                if (Pos < s.Length && s[Pos] == '.')
                {
                    ++Pos;
                    if (!Digits()) throw Fail("digits expected after '.'");
                    integral = false;
                }
                if (Pos < s.Length && (s[Pos] == 'e' || s[Pos] == 'E'))
                {
                    ++Pos;
                    if (Pos < s.Length && (s[Pos] == '+' || s[Pos] == '-')) ++Pos;
                    if (!Digits()) throw Fail("digits expected in the exponent");
                    integral = false;
                }
                string text = s.Substring(start, Pos - start);
                long l;
                if (integral && long.TryParse(text, NumberStyles.AllowLeadingSign, CultureInfo.InvariantCulture, out l))
                {
                    return l;
                }
                double d;
                // Mono's double.Parse throws OverflowException where .NET Core returns infinity.
                if (!double.TryParse(text, NumberStyles.Float, CultureInfo.InvariantCulture, out d) || double.IsInfinity(d))
                {
                    Pos = start;
                    throw Fail("number out of range");
                }
                return d;
            }

            private bool Digits()
            {
                int start = Pos;
                while (Pos < s.Length && s[Pos] >= '0' && s[Pos] <= '9') ++Pos;
                return Pos > start;
            }
        }
    }
}
