#!/usr/bin/env bash
# docs/opcua-nodes.md must be what the adapter builds today (`make docs` regenerates it).
set -euo pipefail
ROOT="$(cd "$(dirname "$0")/../.." && pwd)"
fresh="$(mktemp)"
trap 'rm -f "$fresh"' EXIT
node "$ROOT/adapters/opcua/dist/main.js" --write-node-map "$fresh" > /dev/null
if ! diff -u "$ROOT/docs/opcua-nodes.md" "$fresh"; then
  echo "docs/opcua-nodes.md is stale: run make docs" >&2
  exit 1
fi
echo "docs/opcua-nodes.md is current ($(grep -c '^| `' "$ROOT/docs/opcua-nodes.md") nodes)"
