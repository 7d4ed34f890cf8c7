#!/usr/bin/env bash
# Install the Khronos glTF validator (npm package gltf-validator) into build/node (or $1).
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
dest="${1:-$here/build/node}"
for tool in node npm; do
    command -v "$tool" >/dev/null || { echo "setup_node.sh: '$tool' not found (install Node.js and npm)" >&2; exit 2; }
done
mkdir -p "$dest"
if [ ! -f "$dest/node_modules/gltf-validator/package.json" ]; then
    npm install --prefix "$dest" --no-audit --no-fund --silent gltf-validator >&2
fi
echo "$dest/node_modules"
