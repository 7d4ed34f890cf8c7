#!/usr/bin/env bash
# Install the node packages of the tests and the web viewer into build/node (or $1): the Khronos
# glTF validator, three.js, esbuild (bundles the viewer), puppeteer-core (drives Chromium in
# the viewer's test) and Babylon.js (core and glTF loaders: the reference loader of the export's
# EXT_lights_image_based, tests/browser/test_babylon_ibl.py). Idempotent: when everything is in place it only checks, in well under 1 s.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
dest="${1:-$here/build/node}"
for tool in node npm; do
    command -v "$tool" >/dev/null || { echo "setup_node.sh: '$tool' not found (install Node.js and npm)" >&2; exit 2; }
done
# name@version pins: three's and esbuild's output is part of the committed behaviour; puppeteer-core
# 24 is the last line that runs on Node.js 20 (25 needs 22). Babylon's core and loaders at the same
# version (the loaders' newest; their peer babylonjs-gltf2interface with them).
packages=(gltf-validator three@0.187.0 esbuild@0.28.2 puppeteer-core@24.43.1
    @babylonjs/core@9.28.0 @babylonjs/loaders@9.28.0 babylonjs-gltf2interface@9.28.0)
mkdir -p "$dest"
missing=()
for spec in "${packages[@]}"; do
    name="${spec%@*}"
    [ "$name" = "" ] && name="$spec"
    want="${spec#"$name"}"; want="${want#@}"
    manifest="$dest/node_modules/$name/package.json"
    if [ ! -f "$manifest" ]; then
        missing+=("$spec")
    elif [ -n "$want" ] && ! grep -q "\"version\": *\"$want\"" "$manifest"; then
        missing+=("$spec")
    fi
done
if [ ${#missing[@]} -gt 0 ]; then
    echo "setup_node.sh: installing ${missing[*]}" >&2
    npm install --prefix "$dest" --no-audit --no-fund --silent "${missing[@]}" >&2
fi
echo "$dest/node_modules"
