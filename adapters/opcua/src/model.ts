// The address space: one MotionDeviceSystem instantiated from the official OPC 40010-1
// (Robotics 1.02) ObjectTypes of node-opcua-nodesets, plus SafeState's own variables in its
// own namespace. Every value is read-only; every value goes BadCommunicationError when the
// gateway is lost (OPC 10000-8 §5.2: a client must never read a stale value as Good).
import {
  AddressSpace,
  BaseNode,
  DataType,
  LocalizedText,
  Namespace,
  StatusCode,
  StatusCodes,
  UAObject,
  UAVariable,
  VariantArrayType,
  standardUnits,
  makeEUInformation,
} from "node-opcua";
import { Status } from "./gateway_client";

export const SAFESTATE_NS = "urn:safestate:opcua";
const ROBOTICS_NS = "http://opcfoundation.org/UA/Robotics/";
const DI_NS = "http://opcfoundation.org/UA/DI/";
const AXES = 6;
export const PROGRAM_NAME = "demo"; // the simulated cell's built-in program (SPEC §6)

// OPC 40010-1 OperationalModeEnumeration (ISO 10218-1 5.7 operating modes).
const OPERATIONAL_MODE: Record<string, number> = { T1: 1, T2: 2, AUTO: 3 }; // else 0 OTHER
const ARTICULATED_ROBOT = 1; // MotionDeviceCategoryEnumeration
const ROTARY = 1; // AxisMotionProfileEnumeration
const RAD_TO_DEG = 180 / Math.PI;
// UNECE Rec. 20 common code E96 (OPC 10000-8 §5.6.3 EUInformation).
const degPerSecond = makeEUInformation("E96", "°/s", "degree per second");

type Getter = (s: Status) => [DataType, unknown];

interface Bound {
  v: UAVariable;
  get: Getter;
  last: string; // JSON of the last value set, so an unchanged value is not re-set at 50 Hz
}

export class Model {
  readonly ns: Namespace;
  readonly rob: number;
  readonly di: number;
  readonly mds: UAObject;
  readonly safeState: UAObject;
  readonly taskControl: UAObject;
  private readonly bound: Bound[] = [];
  private softwareRevision: UAVariable | null = null;
  private prev: { t: number; joints: number[] } | null = null;
  private speeds: number[] = new Array(AXES).fill(0);

  constructor(
    private readonly as: AddressSpace,
    private readonly cycleUs: number,
    version: string,
  ) {
    this.ns = as.registerNamespace(SAFESTATE_NS);
    this.rob = as.getNamespaceIndex(ROBOTICS_NS);
    this.di = as.getNamespaceIndex(DI_NS);
    if (this.rob < 0 || this.di < 0) {
      throw new Error("the DI and Robotics nodesets are not loaded");
    }
    this.mds = this.type("MotionDeviceSystemType").instantiate({
      browseName: { name: "MotionDeviceSystem", namespaceIndex: this.ns.index },
      componentOf: this.deviceSet(),
      eventNotifier: 1,
    });
    // Also straight under Objects, so a generic client finds it without knowing DI.
    as.rootFolder.objects.addReference({ referenceType: "Organizes", nodeId: this.mds });
    const server = as.rootFolder.objects.server;
    // OPC 10000-9 §4.8: the Server Object is the root of the HasNotifier/HasEventSource
    // hierarchy, so a SCADA subscribed to Server sees every SafeState alarm.
    server.addReference({ referenceType: "HasNotifier", nodeId: this.mds });
    server.addReference({ referenceType: "HasEventSource", nodeId: this.mds });
    const safety = this.safetyState();
    const device = this.motionDevice();
    const controller = this.controller(version);
    this.taskControl = this.taskControlOf(controller);
    this.relate(controller, "Controls", device);
    this.relate(controller, "HasSafetyStates", safety);
    this.safeState = this.ns.addObject({
      browseName: "SafeState",
      componentOf: this.mds,
      description: "SafeState's own status (SPEC.md): state, sub-state, stop, alarms, first-out cause",
    });
    this.ownVariables();
    this.markBad(StatusCodes.BadCommunicationError);
  }

  // ---------------------------------------------------------------- building
  private type(name: string) {
    const t = this.as.findObjectType(name, this.rob) ?? this.as.findObjectType(name, this.di);
    if (t === null) {
      throw new Error(`ObjectType ${name} not found in the Robotics/DI nodesets`);
    }
    return t;
  }

  private deviceSet(): BaseNode {
    const ds = this.as.rootFolder.objects.getFolderElementByName("DeviceSet", this.di);
    return ds ?? this.as.rootFolder.objects;
  }

  private child(node: BaseNode, path: string, nsIndex?: number): BaseNode {
    let n: BaseNode | null = node;
    for (const name of path.split(".")) {
      const next: BaseNode | null = (n as UAObject).getChildByName(name, nsIndex ?? undefined) as BaseNode | null;
      if (next === null) {
        throw new Error(`no ${path} under ${node.browseName.toString()}`);
      }
      n = next;
    }
    return n;
  }

  private variable(node: BaseNode, path: string): UAVariable {
    return this.child(node, path) as UAVariable;
  }

  private relate(from: BaseNode, refType: string, to: BaseNode): void {
    const rt = this.as.findReferenceType(refType, this.rob);
    if (rt !== null) {
      from.addReference({ referenceType: rt.nodeId, nodeId: to.nodeId });
    }
  }

  private constant(v: UAVariable, dataType: DataType, value: unknown): void {
    v.setValueFromSource({ dataType, value });
  }

  private text(v: UAVariable, s: string): void {
    this.constant(v, DataType.LocalizedText, new LocalizedText({ text: s, locale: "en" }));
  }

  private bind(v: UAVariable, get: Getter): void {
    this.bound.push({ v, get, last: "" });
  }

  private safetyState(): UAObject {
    const folder = this.child(this.mds, "SafetyStates");
    const s = this.type("SafetyStateType").instantiate({
      browseName: { name: "SafetyState", namespaceIndex: this.ns.index },
      componentOf: folder,
      optionals: ["EmergencyStopFunctions", "ProtectiveStopFunctions"],
    });
    // Each safety variable comes from the input it describes, never from the state: the
    // status carries no raw inputs, but the alarm ESTOP_PRESSED is active exactly while the
    // E-stop is pressed (SPEC §7, "while the condition lasts"), in every state, ERROR_LOCKOUT
    // included, where no transition to ESTOP_ACTIVE happens.
    const estopPressed = (st: Status) => st.alarms.includes("ESTOP_PRESSED");
    // OPC 40010-1: a protective stop function that is not Enabled is not Active, and
    // ProtectiveStop is TRUE while one of the *enabled* functions is active. The guard is
    // enabled in AUTO only (in T1/T2 the enabling device protects instead); it is active while
    // its stop holds: the alarm PROTECTIVE_STOP (raised with the stop, latched until a reset).
    // A latched PROTECTIVE_STOP outside AUTO is shown by its alarm condition, not here.
    const gateEnabled = (st: Status) => st.mode === "AUTO";
    const gateActive = (st: Status) => gateEnabled(st) && st.alarms.includes("PROTECTIVE_STOP");
    this.bind(this.variable(s, "ParameterSet.EmergencyStop"), (st) => [DataType.Boolean, estopPressed(st)]);
    this.bind(this.variable(s, "ParameterSet.ProtectiveStop"), (st) => [DataType.Boolean, gateActive(st)]);
    this.bind(this.variable(s, "ParameterSet.OperationalMode"), (st) => [DataType.Int32, OPERATIONAL_MODE[st.mode] ?? 0]);
    const es = this.type("EmergencyStopFunctionType").instantiate({
      browseName: { name: "EmergencyStopCircuit", namespaceIndex: this.ns.index },
      componentOf: this.child(s, "EmergencyStopFunctions"),
    });
    this.constant(this.variable(es, "Name"), DataType.String, "estop (two channels estop.a, estop.b; ISO 13850)");
    this.bind(this.variable(es, "Active"), (st) => [DataType.Boolean, estopPressed(st)]);
    const ps = this.type("ProtectiveStopFunctionType").instantiate({
      browseName: { name: "Gate", namespaceIndex: this.ns.index },
      componentOf: this.child(s, "ProtectiveStopFunctions"),
    });
    this.constant(this.variable(ps, "Name"), DataType.String, "gate (interlocked guard, channels gate.a, gate.b)");
    this.bind(this.variable(ps, "Enabled"), (st) => [DataType.Boolean, gateEnabled(st)]);
    this.bind(this.variable(ps, "Active"), (st) => [DataType.Boolean, gateActive(st)]);
    this.safeLimits(s);
    return s;
  }

  // SPEC §10: the safe limits' configuration and state, SafeState's own variables beside the
  // OPC 40010-1 ones (the companion specification has no safety configuration or reduced
  // mode). Read-only like every variable here; validating is the pendant's (T1/T2 only).
  private safeLimits(safetyState: UAObject): void {
    const o = this.ns.addObject({
      browseName: "SafeLimits",
      componentOf: safetyState,
      description:
        "the active safety configuration (SPEC §10): checksum, validated, reduced mode, recovery; collaborative operation (SPEC §11): fields, SSM, PFL; the brake test (SPEC §12)",
    });
    const add = (name: string, dataType: DataType, description: string, get: Getter, array = false) => {
      const v = this.ns.addVariable({
        browseName: name,
        componentOf: o,
        dataType,
        description,
        ...(array ? { valueRank: 1, arrayDimensions: [0] } : {}),
      });
      this.bind(v, get);
    };
    add("checksum", DataType.String, "checksum of the active safety configuration (8 hex digits, SPEC §10)", (st) => [
      DataType.String,
      st.safety?.checksum ?? "",
    ]);
    add("validated", DataType.Boolean, "the operator has confirmed this checksum (validate_config)", (st) => [
      DataType.Boolean,
      st.safety?.validated ?? false,
    ]);
    add("reduced", DataType.Boolean, "reduced mode is active", (st) => [DataType.Boolean, st.safety?.reduced ?? false]);
    add(
      "reduced_by",
      DataType.String,
      "why reduced mode is active: zone, input, field",
      (st) => [DataType.String, st.safety?.reduced_by ?? []],
      true,
    );
    add("recovery", DataType.Boolean, "a position limit is violated and being recovered from", (st) => [
      DataType.Boolean,
      st.safety?.recovery ?? false,
    ]);
    add("speed_limit", DataType.Double, "TCP speed limit in force, mm/s", (st) => [DataType.Double, st.safety?.speed_limit ?? 0]);
    // SPEC §11 collaborative operation. A value that is null in the status (the function does
    // not act) is a Null variant with GoodNoData: known to be absent, not a lost link.
    const orNone = (v: number | null | undefined) => (v === null || v === undefined ? NOT_ACTING : v);
    add("field_outer", DataType.String, "outer protective field as validated: clear or interrupted (slows: reduced mode)", (st) => [
      DataType.String,
      st.safety?.fields?.outer ?? "",
    ]);
    add("field_inner", DataType.String, "inner protective field as validated: clear or interrupted (stops: rule 9, PERSON_IN_FIELD)", (st) => [
      DataType.String,
      st.safety?.fields?.inner ?? "",
    ]);
    add("separation_mm", DataType.Double, "separation used by speed and separation monitoring, mm (no data while SSM does not act)", (st) => [
      DataType.Double,
      orNone(st.safety?.separation_mm),
    ]);
    add("v_allowed", DataType.Double, "TCP speed SSM allows at that separation, mm/s (0: the robot holds; no data while SSM does not act)", (st) => [
      DataType.Double,
      orNone(st.safety?.v_allowed),
    ]);
    add("pfl", DataType.Boolean, "power and force limiting and collision detection act", (st) => [DataType.Boolean, st.safety?.pfl ?? false]);
    add("contact_force", DataType.Double, "force at the TCP estimated from the drives' torques, N (no data while pfl is off)", (st) => [
      DataType.Double,
      orNone(st.safety?.contact_force),
    ]);
    add("contact_force_limit", DataType.Double, "the body region's quasi-static limit F_qs, N: above it is COLLISION (no data while pfl is off)", (st) => [
      DataType.Double,
      orNone(st.safety?.contact_force_limit),
    ]);
    // SPEC §12 brake test (status safety.brake_test). The hours are null in the status when no
    // pass is on record or none is required: no data, as above.
    add("BrakeTestDueInHours", DataType.Double, "hours until the brake test is due (negative: overdue; no data when no pass is on record or none is required)", (st) => [
      DataType.Double,
      orNone(st.safety?.brake_test?.due_in_h),
    ]);
    add("BrakeTestLastResult", DataType.String, "the latest brake test on record: none, passed or failed", (st) => [
      DataType.String,
      st.safety?.brake_test?.last ?? "",
    ]);
    add("BrakeTestRunning", DataType.Boolean, "the brake test runs (sub-state BRAKE_TEST)", (st) => [
      DataType.Boolean,
      st.safety?.brake_test?.running ?? false,
    ]);
  }

  private motionDevice(): UAObject {
    const folder = this.child(this.mds, "MotionDevices");
    const d = this.type("MotionDeviceType").instantiate({
      browseName: { name: "Robot", namespaceIndex: this.ns.index },
      componentOf: folder,
    });
    this.text(this.variable(d, "Manufacturer"), "SafeState (simulated cell)");
    this.text(this.variable(d, "Model"), "6R arm with IRB 120 kinematics (simulated)");
    this.constant(this.variable(d, "ProductCode"), DataType.String, "SAFESTATE-SIM-6R");
    this.constant(this.variable(d, "SerialNumber"), DataType.String, "SIM-0001");
    this.constant(this.variable(d, "MotionDeviceCategory"), DataType.Int32, ARTICULATED_ROBOT);
    // SafeState has no speed override: programs run at their programmed speed (100 %),
    // T1 is capped at 250 mm/s by the core's monitor, not by an override.
    this.bind(this.variable(d, "ParameterSet.SpeedOverride"), () => [DataType.Double, 100.0]);
    const axes = this.child(d, "Axes");
    const trains = this.child(d, "PowerTrains");
    for (let i = 0; i < AXES; ++i) {
      this.axis(axes, i);
      this.powerTrain(trains, i);
    }
    return d;
  }

  private axis(folder: BaseNode, i: number): void {
    const a = this.type("AxisType").instantiate({
      browseName: { name: `Axis${i + 1}`, namespaceIndex: this.ns.index },
      componentOf: folder,
      optionals: ["ParameterSet.ActualSpeed"],
    });
    this.constant(this.variable(a, "MotionProfile"), DataType.Int32, ROTARY);
    const pos = this.variable(a, "ParameterSet.ActualPosition");
    const speed = this.variable(a, "ParameterSet.ActualSpeed");
    this.constant(this.variable(pos, "EngineeringUnits"), DataType.ExtensionObject, standardUnits.degree);
    this.constant(this.variable(speed, "EngineeringUnits"), DataType.ExtensionObject, degPerSecond);
    this.bind(pos, (st) => [DataType.Double, round(st.joints[i] * RAD_TO_DEG, 1e4)]);
    this.bind(speed, () => [DataType.Double, round(this.speeds[i], 1e3)]);
  }

  private powerTrain(folder: BaseNode, i: number): void {
    const n = i + 1;
    const p = this.type("PowerTrainType").instantiate({
      browseName: { name: `PowerTrain${n}`, namespaceIndex: this.ns.index },
      componentOf: folder,
    });
    const m = this.type("MotorType").instantiate({
      browseName: { name: `Motor${n}`, namespaceIndex: this.ns.index },
      componentOf: p,
      optionals: ["ParameterSet.BrakeReleased"],
    });
    this.text(this.variable(m, "Manufacturer"), "SafeState (simulated cell)");
    this.text(this.variable(m, "Model"), "simulated servo motor with holding brake");
    this.constant(this.variable(m, "ProductCode"), DataType.String, "SAFESTATE-SIM-MOTOR");
    this.constant(this.variable(m, "SerialNumber"), DataType.String, `SIM-M${n}`);
    this.bind(this.variable(m, "ParameterSet.BrakeReleased"), (st) => [DataType.Boolean, st.brakes === "released"]);
    // The simulated cell has no temperature model: say so rather than invent a value.
    const temp = this.variable(m, "ParameterSet.MotorTemperature");
    this.bind(temp, () => [DataType.Double, NO_SENSOR]);
    const drive = this.type("DriveType").instantiate({
      browseName: { name: `Drive${n}`, namespaceIndex: this.ns.index },
      componentOf: p,
    });
    this.constant(this.variable(drive, "ProductCode"), DataType.String, "SAFESTATE-SIM-CIA402");
    this.relate(m, "IsDrivenBy", drive);
    const state = this.ns.addVariable({
      browseName: "AxisState",
      componentOf: drive,
      dataType: DataType.String,
      description: "PLCopen axis state of this axis (Disabled, Standstill, DiscreteMotion, Stopping, ErrorStop)",
    });
    this.bind(state, (st) => [DataType.String, st.axis_state?.[i] ?? ""]);
    const enabled = this.ns.addVariable({
      browseName: "OperationEnabled",
      componentOf: drive,
      dataType: DataType.Boolean,
      description: "CiA 402 'Operation enabled' (all six drives, as the core reports them)",
    });
    this.bind(enabled, (st) => [DataType.Boolean, st.drives === "enabled"]);
  }

  private controller(version: string): UAObject {
    const folder = this.child(this.mds, "Controllers");
    const c = this.type("ControllerType").instantiate({
      browseName: { name: "Controller", namespaceIndex: this.ns.index },
      componentOf: folder,
    });
    this.text(this.variable(c, "Manufacturer"), "SafeState");
    this.text(this.variable(c, "Model"), "SafeState safety supervisor and motion controller");
    this.constant(this.variable(c, "ProductCode"), DataType.String, "SAFESTATE");
    this.constant(this.variable(c, "SerialNumber"), DataType.String, "SIM-C0001");
    this.constant(this.variable(c, "CurrentUser.Level"), DataType.String, "remote (OPC UA adapter)");
    const sw = this.type("SoftwareType").instantiate({
      browseName: { name: "SafeState", namespaceIndex: this.ns.index },
      componentOf: this.child(c, "Software"),
    });
    this.text(this.variable(sw, "Manufacturer"), "SafeState");
    this.text(this.variable(sw, "Model"), "safestate");
    this.softwareRevision = this.variable(sw, "SoftwareRevision");
    this.constant(this.softwareRevision, DataType.String, version);
    return c;
  }

  private taskControlOf(controller: UAObject): UAObject {
    const tc = this.type("TaskControlType").instantiate({
      browseName: { name: "TaskControl", namespaceIndex: this.ns.index },
      componentOf: this.child(controller, "TaskControls"),
    });
    this.text(this.variable(tc, "ComponentName"), "SafeState program task");
    this.bind(this.variable(tc, "ParameterSet.TaskProgramName"), (st) => [
      DataType.String,
      (st.program_length ?? 0) > 0 ? PROGRAM_NAME : "",
    ]);
    this.bind(this.variable(tc, "ParameterSet.TaskProgramLoaded"), (st) => [DataType.Boolean, (st.program_length ?? 0) > 0]);
    const exec = this.ns.addVariable({
      browseName: "ExecutionState",
      componentOf: tc,
      dataType: DataType.String,
      description: "Running, Paused or Idle, from SafeState's sub-state (AUTO_RUNNING, AUTO_PAUSED, ...)",
    });
    this.bind(exec, (st) => [DataType.String, executionState(st)]);
    const index = this.ns.addVariable({
      browseName: "ProgramIndex",
      componentOf: tc,
      dataType: DataType.UInt32,
      description: "waypoint of the program being executed (0-based) of ProgramLength",
    });
    this.bind(index, (st) => [DataType.UInt32, st.program_index ?? 0]);
    const length = this.ns.addVariable({ browseName: "ProgramLength", componentOf: tc, dataType: DataType.UInt32 });
    this.bind(length, (st) => [DataType.UInt32, st.program_length ?? 0]);
    return tc;
  }

  private ownVariables(): void {
    const str = (name: string, description: string, get: (s: Status) => string | null) => {
      const v = this.ns.addVariable({ browseName: name, componentOf: this.safeState, dataType: DataType.String, description });
      this.bind(v, (st) => [DataType.String, get(st) ?? ""]);
    };
    str("state", "SPEC §3 state (BOOT, IDLE, ARMING, OPERATIONAL, STOPPING, ESTOP_ACTIVE, ...)", (s) => s.state);
    str("sub", "sub-state in OPERATIONAL (AUTO_IDLE, AUTO_RUNNING, ...), empty otherwise", (s) => s.sub);
    str("stop", "category of the stop in progress (CAT0, CAT1, CAT2), empty when none", (s) => s.stop);
    str("mode", "effective operating mode (T1, T2, AUTO, NONE)", (s) => s.mode);
    str("owner", "role in control (pendant, remote), empty when none", (s) => s.owner);
    str("first_out_cause", "first-out cause of the current stop or refusal (SPEC §7)", (s) => s.cause);
    str("contactor", "main contactor (open, closed)", (s) => s.contactor);
    str("drives", "drives (enabled, disabled)", (s) => s.drives);
    str("brakes", "brakes (engaged, released)", (s) => s.brakes);
    // SPEC §14: the two contactors' auxiliary contacts and each channel (docs/two-channels.md).
    str("contactor_k1", "K1, channel A's contactor (open, closed)", (s) => s.contactors?.k1 ?? s.contactor);
    str("contactor_k2", "K2, channel B's contactor (open, closed); empty with one channel", (s) => s.contactors?.k2 ?? null);
    for (const [i, name] of ["A", "B"].entries()) {
      const ch = (s: Status) => (s.channels ?? [])[i];
      str(`channel_${name}_state`, `channel ${name}'s state (SPEC §14); empty when there is no channel ${name}`,
        (s) => ch(s)?.state ?? null);
      str(`channel_${name}_digest`, `channel ${name}'s last digest (CRC-32, hex)`, (s) => ch(s)?.digest ?? null);
      const agrees = this.ns.addVariable({
        browseName: `channel_${name}_agrees`,
        componentOf: this.safeState,
        dataType: DataType.Boolean,
        description: `channel ${name} runs, answered its last cycle and agrees with the other channel`,
      });
      this.bind(agrees, (s) => [DataType.Boolean, !!ch(s) && ch(s)!.running && ch(s)!.answered && ch(s)!.agree]);
      const cycle = this.ns.addVariable({
        browseName: `channel_${name}_cycle`,
        componentOf: this.safeState,
        dataType: DataType.Double,
        description: `the last cycle channel ${name} ran`,
      });
      this.bind(cycle, (s) => [DataType.Double, ch(s)?.cycle ?? 0]);
    }
    const tcp = this.ns.addVariable({
      browseName: "tcp_speed",
      componentOf: this.safeState,
      dataType: DataType.Double,
      description: "TCP speed in mm/s",
    });
    this.bind(tcp, (s) => [DataType.Double, s.tcp_speed]);
    this.bind(
      this.ns.addVariable({ browseName: "cycle", componentOf: this.safeState, dataType: DataType.Double, description: "core cycle counter t" }),
      (s) => [DataType.Double, s.t],
    );
  }

  // ---------------------------------------------------------------- updating
  update(s: Status): void {
    this.updateSpeeds(s);
    for (const b of this.bound) {
      const [dataType, value] = b.get(s);
      const key = JSON.stringify(value);
      if (key === b.last) {
        continue;
      }
      b.last = key;
      if (value === NO_SENSOR) {
        b.v.setValueFromSource({ dataType: DataType.Null }, StatusCodes.BadNotConnected);
      } else if (value === NOT_ACTING) {
        b.v.setValueFromSource({ dataType: DataType.Null }, StatusCodes.GoodNoData);
      } else if (Array.isArray(value)) {
        b.v.setValueFromSource({ dataType, arrayType: VariantArrayType.Array, value }, StatusCodes.Good);
      } else {
        b.v.setValueFromSource({ dataType, value }, StatusCodes.Good);
      }
    }
  }

  // ActualSpeed from two successive positions and the core's cycle counter (status comes
  // at 50 Hz; the cycle counter, not the wall clock, gives the elapsed time).
  private updateSpeeds(s: Status): void {
    if (this.prev !== null && s.t > this.prev.t) {
      const dt = ((s.t - this.prev.t) * this.cycleUs) / 1e6;
      for (let i = 0; i < AXES; ++i) {
        this.speeds[i] = ((s.joints[i] - this.prev.joints[i]) / dt) * RAD_TO_DEG;
      }
    }
    this.prev = { t: s.t, joints: s.joints.slice() };
  }

  // The gateway's welcome names the running core's version ("safestate x.y.z").
  setCoreVersion(server: string): void {
    const v = server.replace(/^safestate\s+/, "");
    if (v !== "" && this.softwareRevision !== null) {
      this.softwareRevision.setValueFromSource({ dataType: DataType.String, value: v });
    }
  }

  markBad(code: StatusCode): void {
    this.prev = null;
    for (const b of this.bound) {
      b.last = "";
      b.v.setValueFromSource({ dataType: DataType.Null }, code);
    }
  }

  // Every variable this adapter serves, for the read-only check.
  ownNodes(): UAVariable[] {
    return this.bound.map((b) => b.v);
  }
}

const NO_SENSOR = Symbol("no sensor");
const NOT_ACTING = Symbol("not acting"); // null in the status: the safety function does not act

function round(v: number, scale: number): number {
  return Math.round(v * scale) / scale + 0;
}

function executionState(s: Status): string {
  switch (s.sub) {
    case "AUTO_RUNNING":
    case "MANUAL_RUNNING":
      return "Running";
    case "AUTO_PAUSED":
      return "Paused";
    default:
      return "Idle";
  }
}
