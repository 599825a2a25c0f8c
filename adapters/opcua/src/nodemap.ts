// docs/opcua-nodes.md, generated from the address space this adapter builds (make docs), so
// the published node list cannot drift from the code; ctest opcua_node_map fails when stale.
import { AddressSpace, BaseNode, NodeClass, UAObject, UAVariable } from "node-opcua";

const PREFIX: Record<string, string> = {
  "http://opcfoundation.org/UA/": "",
  "http://opcfoundation.org/UA/DI/": "di:",
  "http://opcfoundation.org/UA/Robotics/": "rob:",
  "urn:safestate:opcua": "ss:",
};

function qualified(as: AddressSpace, node: BaseNode): string {
  const uri = as.getNamespaceArray()[node.browseName.namespaceIndex]?.namespaceUri ?? "";
  return `${PREFIX[uri] ?? `ns${node.browseName.namespaceIndex}:`}${node.browseName.name}`;
}

function typeOf(as: AddressSpace, node: BaseNode): string {
  if (node.nodeClass === NodeClass.Variable) {
    const dt = as.findNode((node as UAVariable).dataType);
    const array = (node as UAVariable).valueRank >= 1 ? "[]" : "";
    return dt ? `${qualified(as, dt)}${array}` : "?";
  }
  if (node.nodeClass === NodeClass.Method) {
    return "Method";
  }
  const td = (node as UAObject).typeDefinitionObj;
  return td ? qualified(as, td) : "Object";
}

function walk(as: AddressSpace, node: BaseNode, path: string, rows: string[], seen: Set<string>): void {
  const key = node.nodeId.toString();
  if (seen.has(key)) {
    return;
  }
  seen.add(key);
  const children = ((node as UAObject).getAggregates?.() ?? [])
    .filter((c) => c.nodeClass !== NodeClass.Method || c.browseName.namespaceIndex !== 0)
    .sort((a, b) => qualified(as, a).localeCompare(qualified(as, b)));
  for (const c of children) {
    const p = `${path}/${qualified(as, c)}`;
    // A&C condition internals are OPC 10000-9's, not ours: list the condition, not its parts.
    if (qualified(as, node) !== "ss:Alarms" || c.nodeClass === NodeClass.Variable) {
      rows.push(`| \`${p}\` | ${typeOf(as, c)} |`);
    }
    if (!/^(0:)?(EngineeringUnits|InputArguments|OutputArguments)$/.test(c.browseName.name ?? "")) {
      walk(as, c, p, rows, seen);
    }
  }
}

export function nodeMap(as: AddressSpace, root: BaseNode): string {
  const rows: string[] = [];
  walk(as, root, qualified(as, root), rows, new Set());
  return [
    "# OPC UA node list (generated)",
    "",
    "Generated from the address space `adapters/opcua` builds (`make docs`; ctest `opcua_node_map`",
    "fails when this copy is stale). Every node under `Objects/ss:MotionDeviceSystem`; prefixes:",
    "`rob:` http://opcfoundation.org/UA/Robotics/, `di:` http://opcfoundation.org/UA/DI/,",
    "`ss:` urn:safestate:opcua, none: the OPC UA namespace. What each means: [opcua.md](opcua.md).",
    "",
    "| browse path | type / data type |",
    "|---|---|",
    ...rows,
    "",
  ].join("\n");
}
