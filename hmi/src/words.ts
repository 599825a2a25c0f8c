// Everything the pendant says in words: result codes (SPEC.md §5), protocol errors,
// states, modes, stop categories, and what the operator should do next.
import type { Mode, State, Status, StopCat } from './api';

// One sentence per SPEC §5 result: what happened and what to do about it.
export const RESULT_WORDS: Record<string, string> = {
  OK: 'Accepted.',
  UNKNOWN_COMMAND: 'The controller does not know this command.',
  BAD_ARGUMENT: 'An argument is out of range (axis 1–6, direction + or −, speed 1–100 %).',
  NOT_CONTROL_OWNER: 'This station does not have control (T1/T2: only the pendant; AUTO: the remote, when one is connected).',
  LOCKED_OUT: 'Locked out by a safety-hardware fault: fix the cause in the alarm list, then power-cycle.',
  ESTOP_ACTIVE: 'An E-stop is pressed: remove the hazard and release every E-stop first, then press Reset.',
  RESET_REQUIRED: 'Press Reset first: the E-stop or a latched alarm must be acknowledged.',
  FAULT_PRESENT: 'The cause of a latched alarm is still there: follow its remedy in the alarm list, then Reset again.',
  MODE_INVALID: 'No valid operating mode: turn the key switch to AUTO, T1 or T2.',
  MODE_BY_SELECTOR_ONLY: 'The operating mode can only be changed with the key switch.',
  GATE_OPEN: 'The guard is open: close the guard (AUTO needs a closed guard).',
  ENABLING_NOT_HELD: 'Hold the enabling device at the centre position.',
  T2_NOT_CONFIRMED: 'T2 (manual high speed) must be confirmed first: press Confirm T2.',
  JOG_NOT_IN_AUTO: 'Jogging is not allowed in AUTO: turn the key switch to T1 or T2.',
  NO_PROGRAM: 'No program is loaded.',
  BUSY: 'The controller is busy arming or stopping: wait until it has finished, then try again.',
  WRONG_STATE: 'This command is not possible in the current state.',
  QUEUE_FULL: 'Too many commands at once: this one was not taken. Try again.',
  CONFIG_NOT_VALIDATED:
    'The safety configuration is not validated: AUTO and T2 need it. In T1 or T2, IDLE, validate it on the Safety page.',
  CHECKSUM_MISMATCH: 'That is not the checksum of the active safety configuration: nothing changed.',
  OUTSIDE_LIMITS:
    'A safe limit is violated or the program leaves the limits (Safety page): in T1, jog back inside first.',
  FIELD_INTERRUPTED: 'A protective field is interrupted: clear it first.',
  BRAKE_TEST_REQUIRED: 'The brake test is due: run it first.',
};

// Protocol errors (protocol.md "Messages"); these come without a result code.
export const ERROR_WORDS: Record<string, string> = {
  BAD_MESSAGE: 'The gateway refused a message from this screen.',
  NOT_HELLO: 'This screen is not registered with the gateway yet: wait for the connection.',
  ROLE_TAKEN: 'Another pendant already has control: this screen is read-only (observer).',
  BAD_TOKEN: 'The gateway needs a valid pendant token.',
  TOO_LARGE: 'A message from this screen was too large.',
  NOT_SIMULATED: 'This cell is not simulated (or this screen is not on the controller host): the simulated devices are unavailable.',
};

export const COMMAND_LABEL: Record<string, string> = {
  reset: 'Reset',
  servo_on: 'Servo on',
  servo_off: 'Servo off',
  start: 'Start',
  pause: 'Pause',
  resume: 'Resume',
  stop: 'Stop',
  jog: 'Jog',
  jog_stop: 'Jog stop',
  confirm_t2: 'Confirm T2',
  set_mode: 'Set mode',
  validate_config: 'Validate configuration',
  brake_test: 'Brake test',
};

export const STATE_WORDS: Record<State, string> = {
  BOOT: 'Starting up',
  ERROR_LOCKOUT: 'Locked out — safety hardware fault',
  ESTOP_ACTIVE: 'Emergency stop',
  ESTOP_RESET_NEEDED: 'E-stop released — reset needed',
  IDLE: 'Idle — drives off',
  ARMING: 'Powering the drives',
  OPERATIONAL: 'Operational — drives on',
  STOPPING: 'Stopping',
};

export const SUB_WORDS: Record<string, string> = {
  AUTO_IDLE: 'ready, program not running',
  AUTO_RUNNING: 'program running',
  AUTO_PAUSED: 'program paused',
  MANUAL_IDLE: 'ready to jog',
  MANUAL_JOGGING: 'jogging',
  MANUAL_RUNNING: 'program test running',
  BRAKE_TEST: 'brake test running',
};

export const MODE_WORDS: Record<Mode, string> = {
  AUTO: 'Automatic',
  T1: 'Manual reduced speed (≤ 250 mm/s)',
  T2: 'Manual high speed',
  NONE: 'No valid mode',
};

export const STOP_WORDS: Record<StopCat, string> = {
  CAT0: 'Cat 0: power removed at once',
  CAT1: 'Cat 1: controlled stop, then power off',
  CAT2: 'Cat 2: controlled stop, power stays on',
};

const MOTION_CMDS = new Set(['start', 'pause', 'resume', 'stop', 'jog', 'jog_stop']);

/** WRONG_STATE with what the current state does allow, so the refusal explains itself. */
function wrongStateWords(cmd: string, s: Status | null): string {
  if (!s) {
    return RESULT_WORDS.WRONG_STATE;
  }
  const where = s.sub ? `${s.state}/${s.sub}` : s.state;
  let hint = '';
  if (s.state === 'IDLE') {
    hint = MOTION_CMDS.has(cmd) ? ' Press Servo on first.' : '';
  } else if (s.state === 'OPERATIONAL') {
    if (cmd === 'servo_on') hint = ' The drives are already on.';
    else if (cmd === 'resume') hint = ' Resume needs a paused program.';
    else if (cmd === 'pause' || cmd === 'stop') hint = ' Nothing is running.';
    else if (cmd === 'jog_stop') hint = ' No jog is running.';
    else if (cmd === 'start' && s.sub === 'AUTO_PAUSED') hint = ' Use Resume or Stop.';
  } else if (s.state === 'STOPPING' || s.state === 'ARMING') {
    hint = ' Wait for the controller to finish.';
  }
  if (cmd === 'confirm_t2' && s.mode !== 'T2') {
    hint = ' Confirm T2 only applies with the key switch at T2.';
  }
  if (cmd === 'servo_off') {
    hint = ' The drives are already off.';
  }
  return `Not possible in ${where}.${hint}`;
}

export function resultWords(code: string, cmd: string, s: Status | null): string {
  if (code === 'WRONG_STATE') {
    return wrongStateWords(cmd, s);
  }
  return RESULT_WORDS[code] ?? `Result ${code}.`;
}

export type Tone = 'red' | 'amber' | 'green' | 'blue' | 'stopping' | 'neutral' | 'offline';

export function toneOf(s: Status): Tone {
  if (s.state === 'ESTOP_ACTIVE' || s.state === 'ERROR_LOCKOUT' || s.alarms.includes('ESTOP_PRESSED')) {
    return 'red';
  }
  if (s.state === 'ESTOP_RESET_NEEDED' || s.reset_lamp === 'on') {
    return 'amber';
  }
  switch (s.state) {
    case 'OPERATIONAL':
      return 'green';
    case 'ARMING':
      return 'blue';
    case 'STOPPING':
      return 'stopping';
    default:
      return 'neutral';
  }
}

const LATCHED = [
  'PROTECTIVE_STOP',
  'DRIVE_FAULT',
  'ARMING_TIMEOUT',
  'T1_SPEED_EXCEEDED',
  'STOP_TIME_EXCEEDED',
  'BRAKE_NOT_ENGAGED',
];

/** Feedback-monitoring alarms (SPEC §7) need more than Reset: say what to do first. */
export const FEEDBACK_ALARM_WORDS: Record<string, string> = {
  CONTACTOR_WELDED:
    'The main contactor did not open (welded): isolate the cell at the main switch and have the contactor replaced before power-cycling.',
  BRAKE_NOT_ENGAGED:
    'A holding brake did not engage: secure the named axis against falling, check the brake, then press Reset.',
};

/** What the operator should do next, in one line. */
export function nextStep(s: Status): string {
  const manual = s.mode === 'T1' || s.mode === 'T2';
  switch (s.state) {
    case 'BOOT':
      return 'Wait: self-test, fieldbus and drives are being checked.';
    case 'ERROR_LOCKOUT':
      if (s.alarms.includes('CONTACTOR_WELDED')) {
        return FEEDBACK_ALARM_WORDS.CONTACTOR_WELDED;
      }
      return s.simulated
        ? 'Fix the cause in the alarm list, then power-cycle (simulated cell: restart make run).'
        : 'Fix the cause in the alarm list, then power-cycle the controller (Reset cannot clear it).';
    case 'ESTOP_ACTIVE':
      return 'Remove the hazard, then release (twist out) every E-stop.';
    case 'ESTOP_RESET_NEEDED':
      return 'Release all E-stops, then press Reset.';
    case 'IDLE': {
      const feedback = s.alarms.find((a) => a in FEEDBACK_ALARM_WORDS);
      if (feedback) {
        return FEEDBACK_ALARM_WORDS[feedback];
      }
      if (s.alarms.some((a) => LATCHED.includes(a)) || s.reset_lamp === 'on') {
        return 'Remove the cause of the alarm (see its remedy), then press Reset.';
      }
      if (s.mode === 'NONE') return 'Turn the key switch to AUTO, T1 or T2.';
      // SPEC §10: a violated limit is left in T1; AUTO and T2 need a validated configuration.
      if (s.safety?.recovery && s.mode !== 'T1') {
        return 'A safe limit is violated (Safety page): turn the key to T1, Servo on, and jog back inside.';
      }
      if (s.safety && !s.safety.validated && s.mode !== 'T1') {
        return 'The safety configuration is not validated: in T1 or T2, validate it on the Safety page (T1 runs without).';
      }
      if (s.mode === 'AUTO') return 'Press Servo on (AUTO needs the guard closed).';
      if (s.mode === 'T2' && !s.t2_confirmed) {
        return 'Press Confirm T2, hold the enabling device at centre, then Servo on.';
      }
      return 'Hold the enabling device at centre, then Servo on.';
    }
    case 'ARMING':
      return manual
        ? 'Keep holding the enabling device at centre while the drives power up.'
        : 'Wait while the contactor, drives and brakes power up.';
    case 'STOPPING':
      return 'Wait until the arm has stopped.';
    case 'OPERATIONAL':
      switch (s.sub) {
        case 'AUTO_IDLE':
          return 'Press Start to run the program, or Servo off.';
        case 'AUTO_RUNNING':
          return 'Program running: Pause holds it, Stop ends it. Opening the guard stops the robot.';
        case 'AUTO_PAUSED':
          return 'Press Resume to continue the program, or Stop to end it.';
        case 'MANUAL_IDLE':
          return 'Keep enabling at centre; hold − or + to jog an axis, or Start to test the program.';
        case 'MANUAL_JOGGING':
          return 'Jogging: release the button to stop. Releasing the enabling device stops at once.';
        case 'MANUAL_RUNNING':
          return 'Program test running: keep the enabling device at centre; Pause or Stop halts it.';
        default:
          return '';
      }
  }
  return '';
}

export const SEVERITY_RANK: Record<string, number> = { lockout: 0, fault: 1, warning: 2, info: 3 };
