#!/usr/bin/env bash
# Must-fail test of the keys of spec/scenario-format.md "More keys, faults and settings":
# for every new expect key (and the expect-once window and replies=), the same scenario
# is run twice, once with the right value (exit 0) and once with a deliberately wrong one
# (exit 1, the message naming the key). Then malformed uses of the new keys, faults and
# config names must exit 2 naming the line. A key that could never fail would show here.
# @req SCN-MORE-KEYS SCN-REPLAY
#
#   tests/integration/more_keys_selftest.sh build/bin/safestate
set -u

BIN=${1:?usage: more_keys_selftest.sh PATH/TO/safestate}
[[ -x $BIN ]] || { echo "more_keys_selftest: not an executable: $BIN" >&2; exit 2; }
DIR=$(mktemp -d "${TMPDIR:-/tmp}/more_keys_selftest.XXXXXX")
trap 'rm -rf "$DIR"' EXIT

checks=0
failures=0
ok() { checks=$((checks + 1)); echo "ok   - $1"; }
not_ok() {
  checks=$((checks + 1))
  failures=$((failures + 1))
  echo "FAIL - $1"
  sed 's/^/       /' "$DIR/all" | head -10
}

run() { # FILE: sets rc, output in $DIR/all
  "$BIN" replay "$1" >"$DIR/all" 2>&1
  rc=$?
}

# Contexts: the lines before the expect, and the cycle the expect is checked at.
RUNNING=$'@100 cmd reset\n@110 cmd servo_on\n@300 cmd start\n'
GUARD=$'@100 cmd reset\n@110 cmd servo_on\n@300 cmd start\n@400 in gate=open\n'
RESET=$'@100 cmd reset\n'
BUTTON=$'@100 in reset_button=1\n@150 in reset_button=0\n'
SELECTOR=$'@100 cmd reset\n@200 in mode.auto=0\n'
TWO_CMDS=$'config max_commands_per_cycle=1\n@100 cmd reset\n@100 cmd servo_on\n'

# pair NAME CONTEXT AT DIRECTIVE RIGHT WRONG
pair() {
  local name=$1 ctx=$2 at=$3 dir=$4 right=$5 wrong=$6
  printf '%s@%s %s %s\n' "$ctx" "$at" "$dir" "$right" >"$DIR/$name.right.scn"
  printf '%s@%s %s %s\n' "$ctx" "$at" "$dir" "$wrong" >"$DIR/$name.wrong.scn"
  run "$DIR/$name.right.scn"
  if [[ $rc -eq 0 ]]; then ok "$name: '$right' holds"; else not_ok "$name: '$right' exit $rc, expected 0"; fi
  run "$DIR/$name.wrong.scn"
  if [[ $rc -eq 1 ]] && grep -qF -- "expected ${wrong}" "$DIR/all"; then
    ok "$name: '$wrong' fails with exit 1"
  elif [[ $rc -eq 1 ]] && grep -qF -- "${wrong%% *}" "$DIR/all"; then
    ok "$name: '$wrong' fails with exit 1"
  else
    not_ok "$name: '$wrong' exit $rc, expected 1 naming it"
  fi
}

pair cause "$GUARD" 400 expect "cause=PROTECTIVE_STOP" "cause=DRIVE_FAULT"
pair cause_none "$RESET" 100 expect "cause=-" "cause=servo_off"
pair cause_signal "$GUARD" 400 expect "cause.signal=gate.a" "cause.signal=gate.b"
pair alarm_number "$GUARD" 400 expect "alarm.PROTECTIVE_STOP.number=201" "alarm.PROTECTIVE_STOP.number=202"
pair alarm_detail "$GUARD" 400 expect "alarm.PROTECTIVE_STOP.detail=gate.a" "alarm.PROTECTIVE_STOP.detail=estop.a"
pair alarm_detail_inactive "$RESET" 100 expect "noalarm=DRIVE_FAULT" "alarm.DRIVE_FAULT.detail=drive.1"
pair mode_requested "$SELECTOR" 220 expect "mode_requested=NONE" "mode_requested=AUTO"
pair axis_state "$GUARD" 400 expect "axis.1.state=Stopping" "axis.1.state=DiscreteMotion"
pair axis_state_running "$RUNNING" 399 expect "axis.1.state=DiscreteMotion" "axis.1.state=Standstill"
pair axis_cia402 "$GUARD" 400 expect "axis.1.cia402=Operation_enabled" "axis.1.cia402=Quick_stop_active"
pair axis_controlword "$GUARD" 400 expect "axis.1.controlword=0x000F" "axis.1.controlword=0x0007"
pair axis_speed "$RUNNING" 399 expect "axis.2.speed>0.01" "axis.2.speed<=0.01"
pair point_speed "$RUNNING" 399 expect "point_speed>1" "point_speed<1"
pair reply_cmd "$RESET" 100 expect "reply.reset=OK" "reply.reset=FAULT_PRESENT"
pair reply_cmd_pending "$TWO_CMDS" 100 expect "reply.servo_on=pending" "reply.servo_on=OK"
pair reply_reset_button "$BUTTON" 150 expect "reply.reset_button=OK" "reply.reset_button=BUSY"
pair replies "$RESET" 100 expect "replies=1" "replies=2"
pair replies_window "$RESET" 99..101 expect "replies=1" "replies=0"
pair standstill "$RUNNING" 399 expect "standstill=no" "standstill=yes"
pair t2_confirmed "$RESET" 100 expect "t2_confirmed=no" "t2_confirmed=yes"
pair owner "$RESET" 100 expect "owner=none" "owner=pendant"
pair expect_once "$RESET" 100..300 expect-once "state=IDLE reply=OK" "state=ARMING"
pair expect_once_same_cycle "$RUNNING" 100..400 expect-once "state=ARMING contactor=closed" "state=IDLE contactor=closed"

# --- malformed: exit 2, naming the line ---------------------------------------------------------
# malformed NAME LINE NEEDLE CONTENT
malformed() {
  printf '%s' "$4" >"$DIR/m_$1.scn"
  run "$DIR/m_$1.scn"
  if [[ $rc -eq 2 ]] && grep -qF -- "m_$1.scn:$2: " "$DIR/all" && grep -qF -- "$3" "$DIR/all"; then
    ok "malformed $1: exit 2 on line $2"
  else
    not_ok "malformed $1: exit $rc, expected 2 naming line $2 and '$3'"
  fi
}
malformed cause_value 2 "cause" $'@0 expect state=BOOT\n@1 expect cause=FIRE\n'
malformed signal_axis 1 "drive.7" $'@1 expect cause.signal=drive.7\n'
malformed alarm_name 1 "alarm.FIRE.number" $'@1 expect alarm.FIRE.number=1\n'
malformed alarm_field 1 "alarm.DRIVE_FAULT.colour" $'@1 expect alarm.DRIVE_FAULT.colour=red\n'
malformed alarm_detail 1 "CONTACTORS" $'@1 expect alarm.ARMING_TIMEOUT.detail=CONTACTORS\n'
malformed axis_number 1 "axis.7.state" $'@1 expect axis.7.state=Standstill\n'
malformed axis_state 1 "Moving" $'@1 expect axis.1.state=Moving\n'
malformed cia402_spaces 1 "Operation" $'@1 expect axis.1.cia402=Operation enabled\n'
malformed controlword 1 "15" $'@1 expect axis.1.controlword=15\n'
malformed axis_speed 1 "axis.N.speed" $'@1 expect axis.1.speed=0\n'
malformed point_speed 1 "point_speed" $'@1 expect point_speed=fast\n'
malformed reply_cmd 1 "reply.fly" $'@1 expect reply.fly=OK\n'
malformed reply_value 1 "MAYBE" $'@1 expect reply.reset=MAYBE\n'
malformed replies_alone 1 "replies=" $'@1 expect replies=1 state=BOOT\n'
malformed replies_once 1 "replies=" $'@1..5 expect-once replies=1\n'
malformed replies_value 1 "many" $'@1 expect replies=many\n'
malformed standstill 1 "maybe" $'@1 expect standstill=maybe\n'
malformed owner 1 "remote" $'@1 expect owner=remote\n'
malformed once_range_cmd 1 "range" $'@1..5 cmd reset\n'
malformed fault_statusword 1 "statusword" $'@1 fault drive 1 statusword 8\n'
malformed fault_slow 1 "slow_enable" $'@1 fault drive 1 slow_enable 0\n'
malformed fault_brake 1 "stuck_released" $'@1 fault brake 7 stuck_released\n'
malformed fault_contactor 1 "welded" $'@1 fault contactor weld\n'
malformed fault_jog_link 1 "jog_link" $'@1 fault jog_link lost\n'
malformed fault_selftest 1 "selftest" $'@1 fault selftest\n'
malformed fault_integrity 1 "integrity" $'@1 fault integrity now\n'
malformed fault_program 1 "program" $'@1 fault program load\n'
malformed config_name 1 "queue_length" $'config queue_length=4\n@1 expect state=BOOT\n'
malformed config_queue 1 "queue_size" $'config queue_size=0\n@1 expect state=BOOT\n'
malformed config_t1 2 "t1_speed_mm_s" $'# T1 must stay within 250 mm/s\nconfig t1_speed_mm_s=300\n@1 expect state=BOOT\n'
malformed config_hold 1 "reset_hold_ms" $'config reset_hold_ms=five\n@1 expect state=BOOT\n'
malformed config_fault_reset 1 "fault_reset_cycles" $'config fault_reset_cycles=0\n@1 expect state=BOOT\n'
malformed config_max_commands 1 "max_commands_per_cycle" $'config max_commands_per_cycle=17\n@1 expect state=BOOT\n'

echo
if [[ $failures -ne 0 ]]; then
  echo "more_keys_selftest: $failures of $checks checks FAILED"
  exit 1
fi
echo "more_keys_selftest: all $checks checks passed"
exit 0
