#!/usr/bin/env bash
# Builds the web viewer (web/) into one self-contained page, three.js bundled in:
#   bash scripts/build_web.sh [--out build/web/prt_viewer.html] [--glb scene.glb]
# With --glb the .glb is embedded, so the page opens by a double click (file://). The node
# packages are installed into build/node on first use (scripts/setup_node.sh).
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
modules=$(bash "$root/scripts/setup_node.sh")
PRT_NODE_MODULES="$modules" exec node "$root/web/build.mjs" "$@"
