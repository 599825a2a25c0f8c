// What a client may change on this server: nothing. The adapter only reports (docs/opcua.md,
// Security); no variable anywhere in the address space — ours, the nodesets' type
// definitions, the Server object's diagnostics, the per-session diagnostics created at run
// time — may be written by any session, anonymous or authenticated. And which user tokens
// are offered: user name and password only (and anonymous on loopback), never X509.
import {
  AddressSpace,
  AttributeIds,
  NodeClass,
  OPCUAServer,
  PermissionType,
  SessionContext,
  StatusCode,
  StatusCodes,
  UAVariable,
  UserTokenType,
  WriteValue,
} from "node-opcua";

// Every permission that changes the address space or its history (OPC 10000-3 §8.55).
const CHANGES =
  PermissionType.WriteAttribute |
  PermissionType.WriteRolePermissions |
  PermissionType.WriteHistorizing |
  PermissionType.Write |
  PermissionType.InsertHistory |
  PermissionType.ModifyHistory |
  PermissionType.DeleteHistory |
  PermissionType.AddReference |
  PermissionType.RemoveReference |
  PermissionType.DeleteNode |
  PermissionType.AddNode;

let permissionsPatched = false;

// A remote session (one that has a `session`) holds none of the changing permissions on any
// node. node-opcua derives a node's UserAccessLevel from these permissions, so a client
// reading UserAccessLevel sees CurrentWrite cleared everywhere, the nodes made at run time
// included, and a write is refused with BadUserAccessDenied (BadNotWritable where the
// AccessLevel itself is read-only). In-process callers (no session: the adapter itself) are
// unaffected. node-opcua has no per-server hook for this, hence the one prototype wrapper.
function denyChangesToSessions(): void {
  if (permissionsPatched) {
    return;
  }
  permissionsPatched = true;
  const proto = SessionContext.prototype as unknown as {
    checkPermission: (this: SessionContext, node: unknown, permission: PermissionType) => boolean;
  };
  const original = proto.checkPermission;
  proto.checkPermission = function (this: SessionContext, node: unknown, permission: PermissionType): boolean {
    if (this.session !== undefined && this.session !== null && (permission & CHANGES) !== 0) {
      return false;
    }
    return original.call(this, node, permission);
  };
}

function refusal(as: AddressSpace, w: WriteValue): StatusCode {
  const node = as.findNode(w.nodeId);
  if (node === null) {
    return StatusCodes.BadNodeIdUnknown;
  }
  const variable = node.nodeClass === NodeClass.Variable ? (node as UAVariable) : null;
  if (w.attributeId === AttributeIds.Value && variable !== null && !variable.isWritable(SessionContext.defaultContext)) {
    return StatusCodes.BadNotWritable;
  }
  return StatusCodes.BadUserAccessDenied;
}

// The Write service itself answers every item with a refusal before any node is touched:
// the backstop should a node somewhere override its own write checks.
export function refuseWrites(server: OPCUAServer): void {
  denyChangesToSessions();
  const as = server.engine.addressSpace;
  if (as === null) {
    throw new Error("refuseWrites: the address space is not built yet");
  }
  server.engine.write = async (_context: unknown, nodesToWrite: WriteValue[]) => nodesToWrite.map((w) => refusal(as, w));
}

// node-opcua offers X509 user identity tokens on every endpoint and, without a trust list of
// users, would accept any certificate. This adapter authenticates users by name and password
// only, so the token type is not offered; a token whose policy is not offered is answered
// BadIdentityTokenInvalid by node-opcua before any certificate check.
export function withoutX509Users(server: OPCUAServer): void {
  for (const endpoint of server.endpoints) {
    for (const description of endpoint.endpointDescriptions()) {
      description.userIdentityTokens = (description.userIdentityTokens ?? []).filter(
        (t) => t.tokenType !== UserTokenType.Certificate,
      );
    }
  }
}
