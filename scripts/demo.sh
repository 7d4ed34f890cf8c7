#!/usr/bin/env bash
# The main job on the bundled default scene and HDRI (environment created on first use).
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
bash "$root/scripts/setup_venv.sh"
cd "$root"
exec "$root/.venv/bin/python" "$root/scripts/demo.py" "$@"
