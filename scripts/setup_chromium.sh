#!/usr/bin/env bash
# Install Debian's Chromium (package chromium) when it is missing, for the web viewer's browser
# test; prints the executable's path. Idempotent: when it is installed it only checks.
set -euo pipefail
as_root() { if [ "$(id -u)" = 0 ]; then "$@"; elif command -v sudo >/dev/null; then sudo "$@"; else return 1; fi; }
for candidate in "${CHROMIUM:-}" /usr/bin/chromium /usr/bin/chromium-browser; do
    if [ -n "$candidate" ] && [ -x "$candidate" ]; then echo "$candidate"; exit 0; fi
done
command -v apt-get >/dev/null || { echo "setup_chromium.sh: install Chromium (or set CHROMIUM to its path)" >&2; exit 2; }
echo "setup_chromium.sh: installing Debian's chromium" >&2
as_root apt-get update -qq >&2
as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null
echo /usr/bin/chromium
