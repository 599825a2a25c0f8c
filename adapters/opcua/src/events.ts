// The event filter result of a monitored item (OPC 10000-4 §7.22.3, §7.4.4.5) made to say
// what the server then delivers. node-opcua checks each select clause by browsing its path
// from the clause's TypeDefinitionId node alone, so it answers Bad for two kinds of clause
// whose values it does deliver:
// - the standard ConditionId clause (TypeDefinitionId ConditionType, an empty BrowsePath,
//   AttributeId NodeId; OPC 10000-9 §5.5.2), which names the condition node itself:
//   BadNothingToDo;
// - a path declared on a supertype or a subtype of the clause's type, e.g. ActiveState/Id with
//   TypeDefinitionId BaseEventType, as many clients (asyncua among them) send it; OPC 10000-4
//   §7.4.4.5 has the path evaluated without regard to BaseEventType: BadNoMatch.
// A strict client drops a field answered Bad, and without ConditionId it can neither match
// nor acknowledge alarms. Those clauses are answered Good here; any other result is kept.
import {
  AddressSpace,
  AttributeIds,
  BaseNode,
  EventFilter,
  EventFilterResult,
  MonitoredItemCreateRequest,
  MonitoredItemCreateResult,
  NodeClass,
  ObjectTypeIds,
  QualifiedName,
  SimpleAttributeOperand,
  StatusCodes,
  Subscription,
  UAObjectType,
  constructBrowsePathFromQualifiedName,
  resolveNodeId,
  sameNodeId,
} from "node-opcua";

const CONDITION_TYPE = resolveNodeId(ObjectTypeIds.ConditionType);

function objectType(as: AddressSpace, clause: SimpleAttributeOperand): UAObjectType | null {
  const t = as.findNode(clause.typeDefinitionId);
  return t !== null && t.nodeClass === NodeClass.ObjectType ? (t as UAObjectType) : null;
}

export function isConditionIdClause(as: AddressSpace, clause: SimpleAttributeOperand): boolean {
  if (clause.attributeId !== AttributeIds.NodeId || (clause.browsePath ?? []).length !== 0) {
    return false;
  }
  // OPC 10000-9 names ConditionType; a subtype of it selects the same condition node.
  const t = objectType(as, clause);
  return sameNodeId(clause.typeDefinitionId, CONDITION_TYPE) || (t !== null && t.isSubtypeOf(CONDITION_TYPE));
}

function resolves(as: AddressSpace, from: BaseNode, path: QualifiedName[]): boolean {
  return as.browsePath(constructBrowsePathFromQualifiedName(from, path)).statusCode.isGood();
}

// The path resolves on the clause's type, one of its supertypes (an inherited declaration) or
// one of its subtypes (a field events of that subtype carry).
function declaredInTheHierarchy(as: AddressSpace, clause: SimpleAttributeOperand, cache: Map<string, boolean>): boolean {
  const path = clause.browsePath ?? [];
  const t = objectType(as, clause);
  if (path.length === 0 || t === null) {
    return false;
  }
  const key = `${t.nodeId.toString()}|${path.map((q) => q.toString()).join("/")}`;
  const known = cache.get(key);
  if (known !== undefined) {
    return known;
  }
  let found = false;
  for (let s: UAObjectType | null = t; s !== null && !found; s = s.subtypeOfObj) {
    found = resolves(as, s, path);
  }
  for (const ns of as.getNamespaceArray()) {
    for (const sub of ns.objectTypeIterator()) {
      if (found) {
        break;
      }
      found = sub.isSubtypeOf(t) && resolves(as, sub, path);
    }
  }
  cache.set(key, found);
  return found;
}

let patched = false;

// Subscription.postCreateMonitoredItem is node-opcua's public step between creating an item
// and answering the request; the result it is given is the one sent to the client.
export function answerDeliveredClauses(as: AddressSpace): void {
  if (patched) {
    return;
  }
  patched = true;
  const cache = new Map<string, boolean>();
  const proto = Subscription.prototype;
  const original = proto.postCreateMonitoredItem;
  proto.postCreateMonitoredItem = function (
    this: Subscription,
    item: Parameters<typeof original>[0],
    request: MonitoredItemCreateRequest,
    result: MonitoredItemCreateResult,
  ): void {
    original.call(this, item, request, result);
    const filter = request.requestedParameters.filter;
    const filterResult = result.filterResult;
    if (!(filter instanceof EventFilter) || !(filterResult instanceof EventFilterResult)) {
      return;
    }
    const codes = filterResult.selectClauseResults ?? [];
    (filter.selectClauses ?? []).forEach((clause, i) => {
      if (i >= codes.length) {
        return;
      }
      const code = codes[i].value;
      if (
        (code === StatusCodes.BadNothingToDo.value && isConditionIdClause(as, clause)) ||
        (code === StatusCodes.BadNoMatch.value && declaredInTheHierarchy(as, clause, cache))
      ) {
        codes[i] = StatusCodes.Good;
      }
    });
  };
}
