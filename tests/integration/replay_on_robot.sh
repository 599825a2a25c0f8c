#!/usr/bin/env bash
# Replays a scenario on a real arm's URDF from the test venv (issue 38): example-robot-data,
# installed by tests/integration/requirements-robots.txt, never copied into the repository.
# Usage: replay_on_robot.sh VENV_PYTHON ur3|ur5|ur10 SAFESTATE FILE.scn
set -euo pipefail
py=$1 robot=$2 bin=$3 scn=$4
share=$("$py" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')/cmeel.prefix/share/example-robot-data/robots
urdf=$share/ur_description/urdf/${robot}_robot.urdf
if [[ ! -f $urdf ]]; then
  echo "replay_on_robot: $urdf missing: pip install -r tests/integration/requirements-robots.txt into the venv (make test does)" >&2
  exit 2
fi
exec "$bin" replay --robot "$urdf" "$scn"
