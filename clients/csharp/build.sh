#!/usr/bin/env bash
# Builds the C# client library, console and NUnit tests with Debian's Mono (mcs, C# 7.2)
# into clients/csharp/bin/. Usage: clients/csharp/build.sh (make csharp runs it).
set -euo pipefail
cd "$(dirname "$0")"
mkdir -p bin
MCS="mcs -langversion:7.2 -codepage:utf8 -nologo -warnaserror+ -debug"
# Debian's libnunit-cil-dev says where NUnit's framework assembly is (nunit.pc).
NUNIT_FRAMEWORK="$(pkg-config --libs nunit | tr ' ' '\n' | sed -n 's/^-r://p' | grep '/nunit\.framework\.dll$' | head -1)"
[[ -f "$NUNIT_FRAMEWORK" ]] || { echo "csharp: nunit.framework.dll not found (pkg-config nunit); run \`make csharp\`" >&2; exit 1; }
$MCS -target:library -out:bin/SafeState.Client.dll -doc:bin/SafeState.Client.xml -nowarn:1591 \
  -r:System.Net.Http.dll $(find SafeState.Client -name '*.cs' | sort)
$MCS -target:exe -out:bin/SafeState.Console.exe -r:bin/SafeState.Client.dll \
  $(find SafeState.Console -name '*.cs' | sort)
$MCS -target:library -out:bin/SafeState.Tests.dll -r:bin/SafeState.Client.dll -r:System.Net.Http.dll \
  -r:"$NUNIT_FRAMEWORK" $(find SafeState.Tests -name '*.cs' | sort)
cp -f "$NUNIT_FRAMEWORK" bin/
echo "csharp: built bin/SafeState.Client.dll bin/SafeState.Console.exe bin/SafeState.Tests.dll"
# The WPF view model of docs/csharp.md must compile against this library (WPF itself is not
# on Mono: the example uses only INotifyPropertyChanged and ObservableCollection).
example="$(mktemp -d)"
trap 'rm -rf "$example"' EXIT
{
  printf 'using System; using System.Linq; using System.ComponentModel; using System.Collections.ObjectModel;\n'
  printf 'using System.Threading.Tasks; using SafeState.Client;\nnamespace DocsExample {\n'
  awk '/^```csharp$/{grab=1; buf=""; next} /^```$/{if (grab && buf ~ /class CellViewModel/) printf "%s", buf; grab=0; next} grab{buf=buf $0 "\n"}' \
    ../../docs/csharp.md
  printf '}\n'
} >"$example/CellViewModel.cs"
grep -q "class CellViewModel" "$example/CellViewModel.cs" || { echo "csharp: no CellViewModel example in docs/csharp.md" >&2; exit 1; }
$MCS -target:library -out:"$example/example.dll" -r:bin/SafeState.Client.dll "$example/CellViewModel.cs"
echo "csharp: the view model example of docs/csharp.md compiles"
