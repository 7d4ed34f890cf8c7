#!/usr/bin/env bash
# Install the web package's node dependencies (web/package.json, pinned by web/package-lock.json)
# into build/node (or $1) with `npm ci`; prints the node_modules path. They are three.js, esbuild
# (bundles the viewer), ESLint, Prettier and TypeScript (the web lint and the API's types),
# puppeteer-core (drives Chromium in the browser tests), the Khronos glTF validator and Babylon.js
# (the reference loader of the export's EXT_lights_image_based, tests/browser/test_babylon_ibl.py).
# Node.js and npm are installed with apt when missing (Debian's nodejs 18 is enough). Idempotent:
# the install is redone only when the lockfile changed (its hash is kept beside node_modules).
# web/node_modules is made a link to it, so the package's tools run in place.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
dest="${1:-$here/build/node}"
as_root() { if [ "$(id -u)" = 0 ]; then "$@"; elif command -v sudo >/dev/null; then sudo "$@"; else return 1; fi; }
if ! command -v node >/dev/null || ! command -v npm >/dev/null; then
    command -v apt-get >/dev/null || { echo "setup_node.sh: install Node.js (18.18 or later) and npm" >&2; exit 2; }
    echo "setup_node.sh: installing Debian's nodejs and npm" >&2
    as_root apt-get update -qq >&2 || { echo "setup_node.sh: cannot run apt-get (not root, no sudo): install nodejs and npm" >&2; exit 2; }
    as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq nodejs npm >/dev/null
fi
lock="$here/web/package-lock.json"
stamp="$dest/.package-lock.sha256"
want="$(cat "$lock" "$here/web/package.json" | sha256sum | cut -d' ' -f1)"  # (contents only: every clone shares one install)
if [ ! -f "$stamp" ] || [ "$(cat "$stamp")" != "$want" ] || [ ! -d "$dest/node_modules" ]; then
    echo "setup_node.sh: npm ci into $dest" >&2
    mkdir -p "$dest"
    rm -f "$stamp"
    cp "$here/web/package.json" "$lock" "$dest/"
    (cd "$dest" && npm ci --no-audit --no-fund --silent >&2)
    echo "$want" >"$stamp"
fi
# The package's own tools (ESLint's config, node running src/) resolve from web/node_modules.
if [ -L "$here/web/node_modules" ] || [ ! -e "$here/web/node_modules" ]; then
    ln -sfn "$dest/node_modules" "$here/web/node_modules"
fi
echo "$dest/node_modules"
