#!/usr/bin/env bash
# The whole test suite in the project's own environment (created on first use): ruff's lint and
# format check first (style fails fast), mypy on the core and the API, the web package's lint
# (ESLint, Prettier's check, TypeScript on the API's types; its node packages by `npm ci` into
# build/node, setup_node.sh), then pytest. Extra arguments go to pytest, e.g.
# `bash scripts/test.sh tests/core/test_sh.py -k poles`; the lanes are folders of tests/
# (docs/architecture.md, "Tests"): the pure lane without bpy `bash scripts/test.sh -m "not blender"`,
# the fast lane without Cycles and the GPU
# `bash scripts/test.sh -m "not cycles and not gpu"`.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
bash "$root/scripts/setup_venv.sh"
cd "$root"
"$root/.venv/bin/ruff" check --quiet .
"$root/.venv/bin/ruff" format --check --quiet .
"$root/.venv/bin/mypy" --no-error-summary
bash "$root/scripts/setup_node.sh" >/dev/null
(cd "$root/web" && ./node_modules/.bin/eslint . && ./node_modules/.bin/prettier --check --log-level warn . &&
    ./node_modules/.bin/tsc -p types/tsconfig.json)
exec "$root/.venv/bin/python" -m pytest "$@"
