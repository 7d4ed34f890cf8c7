#!/usr/bin/env bash
# The whole test suite in the project's own environment (created on first use). Extra arguments
# go to pytest, e.g. `bash scripts/test.sh tests/test_sh.py -k poles`.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
bash "$root/scripts/setup_venv.sh"
cd "$root"
exec "$root/.venv/bin/python" -m pytest "$@"
