// Argument checking of SafeState's own methods. Start, Stop, Pause and Resume take no
// argument (a PLC's cycle start names no program: the cell has one, `demo`). node-opcua
// checks a call's arguments against the declared InputArguments before the method runs (and
// so before its permission check) and answers an extra argument with BadTooManyArguments.
// The issue asks for BadInvalidArgument for bad method arguments, and an anonymous caller
// must still hear BadUserAccessDenied first; so for our methods node-opcua's check lets the
// arguments through and the handler, after the permission check, refuses any with
// BadInvalidArgument (`hasArguments`). Every other method keeps node-opcua's standard check.
// The hook wraps the one exported function node-opcua's call service looks up at each call
// (node-opcua-address-space dist/api/helpers/argument_list.js). node-opcua also asserts that
// the call returns one result per declared argument, so each call of ours gets a declared
// list of its own, as long as what was given. test_opcua.py calls the methods with and
// without arguments, so a node-opcua release that moves any of this fails the tests.
import { Argument, StatusCode, StatusCodes, UAMethod, Variant } from "node-opcua";

interface VerifyResult {
  inputArgumentResults: StatusCode[];
  statusCode: StatusCode;
}
type Verify = (addressSpace: unknown, declared: Argument[], given: Variant[]) => VerifyResult;

// eslint-disable-next-line @typescript-eslint/no-require-imports
const argumentList: { verifyArguments_ArgumentList: Verify } = require("node-opcua-address-space/dist/api/helpers/argument_list.js");

// The declared-argument lists handed out for calls of our methods: one per call.
const ours = new WeakSet<Argument[]>();

let installed = false;
function install(): void {
  if (installed) {
    return;
  }
  const standard = argumentList.verifyArguments_ArgumentList;
  if (typeof standard !== "function") {
    throw new Error("node-opcua's argument check was not found: the method argument policy cannot be installed");
  }
  argumentList.verifyArguments_ArgumentList = (addressSpace, declared, given) => {
    if (!ours.has(declared)) {
      return standard(addressSpace, declared, given ?? []);
    }
    const args = given ?? [];
    // This call's own list, stretched to what was given: the handler decides.
    while (declared.length < args.length) {
      declared.push(new Argument({ name: `unexpected${declared.length + 1}` }));
    }
    return { inputArgumentResults: args.map(() => StatusCodes.Good), statusCode: StatusCodes.Good };
  };
  installed = true;
}

// `method` takes no argument: its handler must answer a call with any BadInvalidArgument.
export function noArguments(method: UAMethod): void {
  install();
  method.getInputArguments = () => {
    const list: Argument[] = [];
    ours.add(list);
    return list;
  };
}

export function hasArguments(inputs: Variant[] | null | undefined): boolean {
  return (inputs ?? []).length > 0;
}
