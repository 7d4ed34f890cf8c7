#!/usr/bin/env bash
# Runs the tests on several Blender versions, each in its own venv (see bpy_venv.sh).
#   bash scripts/test_matrix.sh                 # whole suite on every version
#   bash scripts/test_matrix.sh -m blender      # extra arguments go to pytest
# BPY_VERSIONS overrides the list (space separated).
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
versions=${BPY_VERSIONS:-"4.2.23 4.5.15 5.0.1"}
bash "$root/scripts/setup_venv.sh"   # system libraries and the default venv
status=0
for version in $versions; do
  python=$(bash "$root/scripts/bpy_venv.sh" "$version")
  echo "=== bpy $version"
  (cd "$root" && "$python" -m pytest "$@") || status=1
done
exit $status
