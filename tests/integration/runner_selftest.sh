#!/usr/bin/env bash
# Self-test of the scenario runner: `safestate replay FILE... [--trace]`
# (spec/scenario-format.md). Writes scenario files into a temporary directory and checks
# exit codes, messages and traces. Exits non-zero when any check fails.
# @req SCN-REPLAY SCN-TRACE
#
#   tests/integration/runner_selftest.sh build/bin/safestate
set -u

BIN=${1:?usage: runner_selftest.sh PATH/TO/safestate}
if [[ ! -x $BIN ]]; then
  echo "runner_selftest: not an executable: $BIN" >&2
  exit 2
fi
if ! command -v python3 >/dev/null; then
  echo "runner_selftest: python3 is needed to check the JSON trace" >&2
  exit 2
fi

DIR=$(mktemp -d "${TMPDIR:-/tmp}/runner_selftest.XXXXXX")
trap 'rm -rf "$DIR"' EXIT
# $DIR as a literal inside an extended regex.
DIR_RE=$(printf '%s' "$DIR" | sed 's/[][\\.*^$+?(){}|]/\\&/g')

checks=0
failures=0
ok() { checks=$((checks + 1)); echo "ok   - $1"; }
not_ok() {
  checks=$((checks + 1))
  failures=$((failures + 1))
  echo "FAIL - $1"
  if [[ $# -gt 1 ]]; then
    echo "       exit code: $rc"
    sed 's/^/       stdout: /' "$DIR/out" | head -20
    sed 's/^/       stderr: /' "$DIR/err" | head -20
  fi
}

# replay ARGS...: runs the binary; sets rc; stdout in $DIR/out, stderr in $DIR/err, both
# together in $DIR/all (human messages go to stdout, or to stderr when tracing).
rc=0
replay() {
  "$BIN" replay "$@" >"$DIR/out" 2>"$DIR/err"
  rc=$?
  cat "$DIR/out" "$DIR/err" >"$DIR/all"
}

expect_rc() { # NAME CODE
  if [[ $rc -eq $2 ]]; then ok "$1: exit $2"; else not_ok "$1: exit $rc, expected $2" show; fi
}

# expect_text NAME FILE NEEDLE: FILE contains the fixed string NEEDLE.
expect_text() {
  if grep -qF -- "$3" "$2"; then ok "$1: says '$3'"; else not_ok "$1: '$3' not found" show; fi
}

# expect_regex NAME FILE REGEX (extended)
expect_regex() {
  if grep -qE -- "$3" "$2"; then ok "$1: matches /$3/"; else not_ok "$1: nothing matches /$3/" show; fi
}

# expect_count NAME FILE NEEDLE N: exactly N lines contain NEEDLE.
expect_count() {
  local n
  n=$(grep -cF -- "$3" "$2")
  if [[ $n -eq $4 ]]; then ok "$1: $4 line(s) with '$3'"; else not_ok "$1: $n line(s) with '$3', expected $4" show; fi
}

# --- scenario files -----------------------------------------------------------------------

# The example of spec/scenario-format.md: must pass.
cat >"$DIR/pass.scn" <<'EOF'
# E-stop needs a deliberate reset after release (ISO 13849-1 5.2.2)
@200  expect state=ESTOP_RESET_NEEDED reset_lamp=on
@201  cmd reset
@201  expect state=IDLE
@300  in estop.a=0                 # one channel is enough to stop
@300  expect state=ESTOP_ACTIVE stop=CAT0 contactor=open brakes=engaged
@310  in estop.b=0
@400  in estop=released
@401..600 expect state=ESTOP_RESET_NEEDED   # release alone never restarts
@601  cmd reset
@601  expect state=IDLE reply=OK
EOF

# Commands are judged by the core, not the parser (SPEC §5): must pass.
cat >"$DIR/commands.scn" <<'EOF'
config discrepancy_ms=40
@200 expect state=ESTOP_RESET_NEEDED
@201 cmd reset
@201 expect state=IDLE reply=OK
@210 expect reply=OK                      # still the latest command
@220 cmd set_mode T1
@220 expect reply=MODE_BY_SELECTOR_ONLY
@230 cmd fly_to_the_moon 1 2
@230 expect reply=UNKNOWN_COMMAND
@240 cmd jog 9 +
@240 expect reply=BAD_ARGUMENT
@250 cmd start
@250 expect reply=WRONG_STATE state=IDLE
@260 cmd from=remote reset
@260 expect reply=NOT_CONTROL_OWNER
@260..300 expect state=IDLE contactor=open drives=disabled brakes=engaged tcp_speed<=0.5
EOF

# An expect that cannot hold right after boot.
cat >"$DIR/fail.scn" <<'EOF'
# the cell boots to ESTOP_RESET_NEEDED, never OPERATIONAL by itself
@200 expect state=OPERATIONAL
EOF

# Several failures: each line reported once, the run goes on.
cat >"$DIR/fail_many.scn" <<'EOF'
@0 expect reply=OK                 # no command sent yet
@0..150 expect state=BOOT          # BOOT ends within 100 cycles: fails once
@300 expect state=IDLE noalarm=ESTOP_PRESSED
EOF

# --- 1. a correct file passes -----------------------------------------------------------------

replay "$DIR/pass.scn"
expect_rc "spec example" 0
expect_text "spec example summary" "$DIR/all" "PASS $DIR/pass.scn"

replay "$DIR/commands.scn"
expect_rc "commands judged by the core" 0
expect_text "commands summary" "$DIR/all" "PASS $DIR/commands.scn"

# A range written after the lines it covers (as in the shared t1-jog.scn) is not malformed.
cat >"$DIR/late_range.scn" <<'EOF'
@300 cmd reset
@300 expect state=IDLE reply=OK
@250..299 expect state=ESTOP_RESET_NEEDED reset_lamp=on
EOF
replay "$DIR/late_range.scn"
expect_rc "range written after later lines" 0

# --- 2. a wrong expect fails, naming file, line, cycle, expected and found ---------------------

replay "$DIR/fail.scn"
expect_rc "wrong expect" 1
expect_regex "wrong expect message" "$DIR/all" \
  "^$DIR_RE/fail\.scn:2: cycle 200: expected state=OPERATIONAL, found state=[A-Z_]+$"
expect_text "wrong expect summary" "$DIR/all" "FAIL $DIR/fail.scn"

replay "$DIR/fail_many.scn"
expect_rc "several failures" 1
expect_text "reply before any command" "$DIR/all" \
  "$DIR/fail_many.scn:1: cycle 0: expected reply=OK, found reply=none"
expect_count "a range reports its first failing cycle only" "$DIR/all" "$DIR/fail_many.scn:2: cycle " 1
expect_regex "range message" "$DIR/all" \
  "^$DIR_RE/fail_many\.scn:2: cycle [0-9]+: expected state=BOOT, found state=[A-Z_]+$"
expect_regex "the run goes on after a failure" "$DIR/all" \
  "^$DIR_RE/fail_many\.scn:3: cycle 300: expected state=IDLE, found state=[A-Z_]+$"

# --- 3. malformed files exit 2 and name the line ----------------------------------------------

# malformed NAME LINE NEEDLE CONTENT
malformed() {
  local file="$DIR/malformed_$1.scn"
  printf '%s' "$4" >"$file"
  replay "$file"
  expect_rc "malformed $1" 2
  expect_text "malformed $1 names the line" "$DIR/all" "$file:$2: "
  expect_text "malformed $1 says what" "$DIR/all" "$3"
  if grep -qE '^(PASS|FAIL) ' "$DIR/all"; then not_ok "malformed $1 was run" show; else ok "malformed $1 not run"; fi
}

malformed bad_time 2 "time" $'# header\n@abc expect state=IDLE\n'
malformed negative_time 1 "time" $'@-1 expect state=IDLE\n'
malformed backwards 3 "backwards" $'@100 expect state=IDLE\n@200 cmd reset\n@150 expect state=IDLE\n'
malformed range_on_cmd 2 "range" $'@0 expect state=BOOT\n@10..20 cmd reset\n'
malformed range_reversed 1 "range" $'@20..10 expect state=IDLE\n'
malformed unknown_directive 2 "wait" $'@0 expect state=BOOT\n@5 wait 10\n'
malformed no_time 1 "expect" $'expect state=IDLE\n'
malformed unknown_key 1 "colour" $'@5 expect colour=red\n'
malformed unknown_state 2 "RUNNING" $'\n@5 expect state=RUNNING\n'
malformed unknown_alarm 1 "FIRE" $'@5 expect alarm=FIRE\n'
malformed empty_expect 1 "expect" $'@5 expect\n'
malformed unknown_input 1 "door" $'@5 in door=open\n'
malformed bad_input_value 1 "estop" $'@5 in estop=open\n'
malformed config_after_at 3 "config" $'config cycle_us=500\n@0 expect state=BOOT\nconfig max_stop_ms=500\n'
malformed config_invalid 2 "cycle_us" $'# too fast\nconfig cycle_us=100\n@0 expect state=BOOT\n'
malformed config_unknown 1 "warp_factor" $'config warp_factor=9\n'
malformed bad_fault 1 "fault" $'@5 fault drive 7 fault\n'
malformed bad_fault_word 2 "fault" $'@0 expect state=BOOT\n@5 fault fieldbus down\n'
malformed bad_from 1 "from" $'@5 cmd from=observer reset\n'
malformed bad_speed 1 "tcp_speed" $'@5 expect tcp_speed=fast\n'
# the simulated person's keys (docs/collaborative.md "The simulated person")
malformed person_too_fast 2 "over 2000" $'@0 person at 4000 0\n@5 person walk 1000 0 2500\n'
malformed person_unknown 1 "unknown person action" $'@0 person jump 0 0\n'
malformed person_missing 2 "needs X Y SPEED, found 2" $'@0 person at 4000 0\n@5 person walk 1000 0\n'
malformed person_absent 1 "no person in the cell" $'@0 person walk 1000 0 1600\n'
malformed person_fields 1 "person_fields" $'config person_fields=900,1000\n@0 expect state=BOOT\n'

# --- 4. unreadable files --------------------------------------------------------------------------

replay "$DIR/does_not_exist.scn"
expect_rc "missing file" 2
expect_text "missing file is named" "$DIR/all" "$DIR/does_not_exist.scn"

# --- 5. several files: the worst exit code wins ----------------------------------------------

replay "$DIR/pass.scn" "$DIR/fail.scn"
expect_rc "pass + fail" 1
expect_text "pass + fail: first summary" "$DIR/all" "PASS $DIR/pass.scn"
expect_text "pass + fail: second summary" "$DIR/all" "FAIL $DIR/fail.scn"

replay "$DIR/fail.scn" "$DIR/malformed_bad_time.scn" "$DIR/pass.scn"
expect_rc "fail + malformed + pass" 2
expect_text "every file is run" "$DIR/all" "PASS $DIR/pass.scn"

replay "$DIR/pass.scn" "$DIR/commands.scn"
expect_rc "pass + pass" 0

# --- 6. --trace -----------------------------------------------------------------------------------

replay --trace "$DIR/pass.scn"
expect_rc "trace run" 0
cp "$DIR/out" "$DIR/trace1.jsonl"
if [[ -s $DIR/trace1.jsonl ]]; then ok "trace is not empty"; else not_ok "trace is empty" show; fi
if python3 -c 'import json,sys; [json.loads(l) for l in sys.stdin]' <"$DIR/trace1.jsonl"; then
  ok "trace parses line by line"
else
  not_ok "trace does not parse as JSON Lines" show
fi
if grep -qE '^(PASS|FAIL) ' "$DIR/out"; then not_ok "human messages on stdout while tracing" show; else ok "stdout is only the trace"; fi
expect_text "summary goes to stderr while tracing" "$DIR/err" "PASS $DIR/pass.scn"
expect_text "reply line" "$DIR/trace1.jsonl" '{"t":201,"reply":{"cmd":"reset","from":"pendant","result":"OK"}}'
expect_text "reply line" "$DIR/trace1.jsonl" '{"t":601,"reply":{"cmd":"reset","from":"pendant","result":"OK"}}'

# Structure: keys in order, the first cycle always, one line per change, times in order.
cat >"$DIR/check_trace.py" <<'EOF'
import json, sys

STATE_KEYS = ["t", "state", "sub", "mode", "stop", "contactor", "drives", "brakes", "reset_lamp", "tcp_speed", "alarms"]
problems = []
last_t = -1
last_state = None
first = True
for n, raw in enumerate(sys.stdin, 1):
    line = json.loads(raw)
    keys = list(line.keys())
    if keys == ["file"]:
        last_t, last_state, first = -1, None, True  # a new file starts from a fresh cell
        continue
    if first:
        if keys != STATE_KEYS or line["t"] != 0:
            problems.append(f"line {n}: the first line must be the state at t=0, got {raw.strip()}")
        first = False
    if keys == STATE_KEYS:
        body = {k: v for k, v in line.items() if k != "t"}
        if body == last_state:
            problems.append(f"line {n}: state line without a change")
        last_state = body
        if not isinstance(line["tcp_speed"], (int, float)) or round(line["tcp_speed"], 1) != line["tcp_speed"]:
            problems.append(f"line {n}: tcp_speed must be a number rounded to 0.1")
        if line["sub"] == "-" or line["stop"] == "-":
            problems.append(f"line {n}: null must be written as null")
        if not isinstance(line["alarms"], list):
            problems.append(f"line {n}: alarms must be an array")
    elif keys == ["t", "reply"]:
        if list(line["reply"].keys()) != ["cmd", "from", "result"]:
            problems.append(f"line {n}: reply keys {list(line['reply'].keys())}")
        if line["reply"]["from"] not in ("pendant", "remote", "reset_button"):
            problems.append(f"line {n}: bad from")
    else:
        problems.append(f"line {n}: unexpected keys {keys}")
    if line["t"] < last_t:
        problems.append(f"line {n}: t goes backwards")
    last_t = line["t"]
for p in problems[:20]:
    print(p)
sys.exit(1 if problems else 0)
EOF
if python3 "$DIR/check_trace.py" <"$DIR/trace1.jsonl"; then ok "trace structure"; else not_ok "trace structure" show; fi
expect_text "ESTOP_ACTIVE appears in the trace" "$DIR/trace1.jsonl" '"state":"ESTOP_ACTIVE"'

replay --trace "$DIR/pass.scn"
cp "$DIR/out" "$DIR/trace2.jsonl"
if cmp -s "$DIR/trace1.jsonl" "$DIR/trace2.jsonl"; then ok "two runs give identical traces"; else not_ok "traces differ between runs"; fi

replay --trace "$DIR/commands.scn"
expect_rc "trace of commands" 0
expect_text "unknown command traced as written" "$DIR/out" \
  '{"t":230,"reply":{"cmd":"fly_to_the_moon","from":"pendant","result":"UNKNOWN_COMMAND"}}'
expect_text "remote source traced" "$DIR/out" \
  '{"t":260,"reply":{"cmd":"reset","from":"remote","result":"NOT_CONTROL_OWNER"}}'
if python3 "$DIR/check_trace.py" <"$DIR/out"; then ok "commands trace structure"; else not_ok "commands trace structure" show; fi

replay --trace "$DIR/fail.scn"
expect_rc "trace of a failing file" 1
expect_text "failure message on stderr while tracing" "$DIR/err" "$DIR/fail.scn:2: cycle 200: expected state=OPERATIONAL"

replay --trace "$DIR/pass.scn" "$DIR/commands.scn"
expect_rc "trace of two files" 0
cp "$DIR/out" "$DIR/trace_two.jsonl"
if python3 -c 'import json,sys; [json.loads(l) for l in sys.stdin]' <"$DIR/trace_two.jsonl"; then
  ok "two-file trace parses"
else
  not_ok "two-file trace does not parse" show
fi
file_lines=$(python3 -c '
import json, sys
print(" ".join(json.loads(l)["file"] for l in sys.stdin if list(json.loads(l).keys()) == ["file"]))' <"$DIR/trace_two.jsonl")
if [[ $file_lines == "$DIR/pass.scn $DIR/commands.scn" ]]; then
  ok "a {\"file\":PATH} line before each file"
else
  not_ok "file lines: '$file_lines'"
fi
if [[ $(head -1 "$DIR/trace_two.jsonl") == "{\"file\":\"$DIR/pass.scn\"}" ]]; then
  ok "the first line names the first file"
else
  not_ok "the first line does not name the first file"
fi
if python3 "$DIR/check_trace.py" <"$DIR/trace_two.jsonl"; then ok "two-file trace structure"; else not_ok "two-file trace structure"; fi
# The second file's part equals its own trace.
sed -n "/^{\"file\":\"${DIR//\//\\/}\/commands.scn\"}$/,\$p" "$DIR/trace_two.jsonl" | tail -n +2 >"$DIR/part.jsonl"
"$BIN" replay --trace "$DIR/commands.scn" >"$DIR/alone.jsonl" 2>/dev/null
if cmp -s "$DIR/part.jsonl" "$DIR/alone.jsonl"; then ok "each file starts from a fresh cell"; else not_ok "a file's trace depends on the file before it"; fi

echo
if [[ $failures -ne 0 ]]; then
  echo "runner_selftest: $failures of $checks checks FAILED"
  exit 1
fi
echo "runner_selftest: all $checks checks passed"
exit 0
