// Start, Stop, Pause, Resume of the program, for the plant in AUTO: each is forwarded as
// the `remote` command of the same name (Start from IDLE sends `servo_on` first), and the
// core's answer comes back as the OPC UA status (mapped below) and as the output argument
// Result (the SafeState code itself).
// Nothing only the pendant may do (reset, jog, servo_on in manual modes, T2 confirm) is
// reachable: ISO 10218-1 5.3.5 single point of control, enforced again by the gateway.
import {
  AddressSpace,
  Argument,
  MethodIds,
  CallMethodResultOptions,
  DataType,
  ISessionContext,
  PermissionType,
  StatusCode,
  StatusCodes,
  UAMethod,
  UserNameIdentityToken,
  Variant,
  WellKnownRoles,
  makeRoles,
} from "node-opcua";
import { hasArguments, noArguments } from "./arguments";
import { GatewayClient } from "./gateway_client";
import { Model, PROGRAM_NAME } from "./model";

const STATUS_OF: Record<string, StatusCode> = {
  OK: StatusCodes.Good,
  NOT_CONTROL_OWNER: StatusCodes.BadUserAccessDenied,
  BAD_ARGUMENT: StatusCodes.BadInvalidArgument,
  UNKNOWN_COMMAND: StatusCodes.BadInvalidArgument,
  QUEUE_FULL: StatusCodes.BadTooManyOperations,
  TIMEOUT: StatusCodes.BadTimeout,
  GATEWAY_UNAVAILABLE: StatusCodes.BadCommunicationError,
};

// Every other refusal (GATE_OPEN, WRONG_STATE, BUSY, ESTOP_ACTIVE, LOCKED_OUT, ...) says the
// robot is not in a state that allows the command.
export function statusOf(result: string): StatusCode {
  return STATUS_OF[result] ?? StatusCodes.BadInvalidState;
}

const RESULT_ARG = new Argument({
  name: "Result",
  dataType: DataType.String,
  valueRank: -1,
  description: { text: "SafeState result code (SPEC.md §5): OK, GATE_OPEN, NOT_CONTROL_OWNER, ..." },
});

interface Spec {
  name: string;
  cmd: string;
  description: string;
}

const METHODS: Spec[] = [
  {
    name: "Start",
    cmd: "start",
    description: `power the drives if they are off (servo_on), then start the loaded program "${PROGRAM_NAME}" (-> AUTO_RUNNING)`,
  },
  { name: "Stop", cmd: "stop", description: "stop the program (Cat 2 stop, then AUTO_IDLE)" },
  { name: "Pause", cmd: "pause", description: "pause the program (Cat 2 stop, then AUTO_PAUSED)" },
  { name: "Resume", cmd: "resume", description: "resume a paused program (AUTO_PAUSED -> AUTO_RUNNING)" },
];

export function authenticated(context: ISessionContext): boolean {
  const session = (context as unknown as { session?: { userIdentityToken?: unknown } }).session;
  return session?.userIdentityToken instanceof UserNameIdentityToken;
}

// Methods that only concern the caller's own subscriptions (OPC 10000-5 / 10000-9): a
// read-only client needs them to keep an alarm list and its data changes in step.
const READ_LIKE = new Set([
  MethodIds.ConditionType_ConditionRefresh,
  MethodIds.ConditionType_ConditionRefresh2,
  MethodIds.Server_GetMonitoredItems,
  MethodIds.Server_ResendData,
]);

// Every other method — ours, A&C Acknowledge/Confirm/AddComment/Enable/Disable/shelving,
// the Server object's — needs an authenticated user (IEC 62443-3-3 SR 1.1, SR 2.1).
export function requireAuthenticatedCalls(as: AddressSpace): void {
  as.addMethodCallInterceptor((context: ISessionContext, _object: unknown, method: UAMethod) => {
    const standard = method.nodeId.namespace === 0 && READ_LIKE.has(method.nodeId.value as number);
    return standard || authenticated(context) ? StatusCodes.Good : StatusCodes.BadUserAccessDenied;
  });
}

function result(statusCode: StatusCode, code: string): CallMethodResultOptions {
  return { statusCode, outputArguments: [new Variant({ dataType: DataType.String, value: code })] };
}

const ARMING_MS = 3000; // contactor 100 + drives 500 + brakes 300 ms (SPEC §4 ARMING), with margin

// A plant's cycle start: from IDLE the drives are powered first (`servo_on`, which a
// remote may send only in AUTO, with the guard closed: ISO 10218-1 5.4 / ISO 10218-2
// 5.10), then the program starts. Every refusal on the way is the answer, so a start with
// the gate open answers GATE_OPEN and one in T1 NOT_CONTROL_OWNER, straight from the core.
async function start(gateway: GatewayClient): Promise<string> {
  if (gateway.latest?.state === "IDLE") {
    const armed = await gateway.command("servo_on");
    if (armed !== "OK") {
      return armed;
    }
    // Arming that fails falls back to IDLE with its alarm: the start then gets the core's
    // own answer (WRONG_STATE) rather than one made up here.
    await gateway.waitFor((s) => s.state !== "ARMING" && s.state !== "IDLE", ARMING_MS);
  }
  return gateway.command("start");
}

export function addMethods(model: Model, gateway: GatewayClient): UAMethod[] {
  return METHODS.map((m) => {
    const method = model.ns.addMethod(model.taskControl, {
      browseName: m.name,
      description: m.description,
      inputArguments: [],
      outputArguments: [RESULT_ARG],
    });
    // Any argument is BadInvalidArgument (after the permission check), and nothing is sent.
    noArguments(method);
    // Anonymous sessions may browse and read, never call (the issue: "methods always need
    // an authenticated user"); UserExecutable then says so to UaExpert as well.
    method.setRolePermissions([
      { roleId: makeRoles(WellKnownRoles.Anonymous)[0], permissions: PermissionType.Browse | PermissionType.Read },
      {
        roleId: makeRoles(WellKnownRoles.AuthenticatedUser)[0],
        permissions: PermissionType.Browse | PermissionType.Read | PermissionType.Call,
      },
    ]);
    method.bindMethod(async (inputs: Variant[], context: ISessionContext): Promise<CallMethodResultOptions> => {
      if (!authenticated(context)) {
        return result(StatusCodes.BadUserAccessDenied, "NOT_AUTHENTICATED");
      }
      if (hasArguments(inputs)) {
        return { statusCode: StatusCodes.BadInvalidArgument };
      }
      const code = m.cmd === "start" ? await start(gateway) : await gateway.command(m.cmd);
      return result(statusOf(code), code);
    });
    return method;
  });
}
