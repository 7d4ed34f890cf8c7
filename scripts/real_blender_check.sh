#!/usr/bin/env bash
# Runs the add-on in a real Blender program with a window, which the test suite (bpy as a module,
# headless) cannot: the modal bake through Blender's own event loop, undo and redo, Esc, and the
# shared-buffer Embree path inside a program that links its own Embree.
#
#   sudo bash scripts/real_blender_check.sh [WORK_DIR]     # default WORK_DIR: build/real-blender
#
# The Blender is Debian 13's package (Blender 4.3), installed with python3-numpy (only a
# recommendation of the package), Xvfb, ImageMagick and procps into a debootstrap folder in
# WORK_DIR (~1.5 GB, about 2 minutes the first time, reused afterwards); the zip is built from
# this checkout (the .venv of scripts/setup_venv.sh). Needs root (debootstrap, chroot, mounts)
# and the Debian package registry. Not part of .ci/run. Prints one line per check (the checks are
# the CHECKS of real_blender_check.py), saves X screenshots of the run in WORK_DIR/shots and exits
# 1 if a check fails. When the set-up fails (no Blender, the zip not built or not installed, the
# extension not enabled) every check is printed as failed with the set-up error.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
work=$(mkdir -p "${1:-$root/build/real-blender}" && cd "${1:-$root/build/real-blender}" && pwd)
chroot_dir=$work/trixie
inside=/root/prt-check
packages="blender python3-numpy xvfb xauth imagemagick procps"

# Prints every check with its verdict (all failed when a set-up error is given) and ends the
# script: exit 0 only when every check passed.
report() {
  python3 - "$root/scripts/real_blender_check.py" "$work" "$@" <<'PY' || exit 1
import ast, glob, json, os, shutil, sys
source, work, setup_error = sys.argv[1], sys.argv[2], " ".join(sys.argv[3:])
tree = ast.parse(open(source).read())
names = next(ast.literal_eval(node.value) for node in tree.body if isinstance(node, ast.Assign)
             and any(getattr(t, "id", None) == "CHECKS" for t in node.targets))
path = os.path.join(work, "result.json")
r = json.load(open(path)) if not setup_error and os.path.isfile(path) else {}
r.setdefault("checks", {})
setup_error = setup_error or r.get("setup_error", "")
log_path = os.path.join(work, "blender.log")
log = open(log_path, errors="replace").read() if os.path.isfile(log_path) else ""
r["checks"]["no Python traceback in Blender's output"] = bool(log) and "Traceback" not in log
checks = {name: not setup_error and r["checks"].get(name) is True for name in names}
# The screens that real_blender_shots.py picked: the display turned on, the turned lighting drawn.
shots = glob.glob(os.path.join(work, "shots", "screen_*.png"))
for shot, name in zip(r.get("turn_shots") or [], ("display_on.png", "display_rotated.png")):
    if shot:
        shutil.copy(os.path.join(work, "shots", shot), os.path.join(work, name))
if "turn_redraw_seconds" in r:
    print(f"the turn drawn after {r['turn_redraw_seconds']} s; Suzanne changed by {r.get('turn_viewport_change')} /255")
if "blender" in r:
    print(f"Blender {r['blender']} (Python {r['python']}); Embree bound from {r.get('binding_library')}")
for name, ok in checks.items():
    print(("PASS  " if ok else "FAIL  ") + name + ("" if ok or not setup_error else f"  (set-up failed: {setup_error})"))
if "exception" in r:
    print(r["exception"])
print(f"{sum(checks.values())}/{len(checks)} checks passed")
if shots:
    print(f"screenshots: {work}/display_on.png, {work}/display_rotated.png, {work}/shots/")
colour = r.get("colour", {})
for key in ("view_transform", "screen_pixels_compared", "screen_vs_offscreen_mean", "screen_vs_offscreen_p99",
            "dirty_after_save", "dirty_after_table_build", "timer_rebuilt_table", "timer_followed_filmic"):
    print(f"colour: {key} = {colour.get(key)}")
for name, (mean, top, count) in colour.get("per_transform", {}).items():
    print(f"colour: {name}: display vs save_render mean {mean:.2f} max {top:.2f} /255 over {count} pixels")
for error in colour.get("errors", []):
    print("colour error:", error)
if os.path.isfile(os.path.join(work, "colour", "prt_vs_cycles.png")):
    print(f"PRT beside Cycles: {work}/colour/prt_vs_cycles.png")
sys.exit(0 if checks and all(checks.values()) else 1)
PY
  exit 0
}

rm -f "$work/result.json" "$work/blender.log" "$work"/display_*.png
if [ ! -x "$chroot_dir/usr/bin/blender" ] || ! chroot "$chroot_dir" dpkg -s $packages >/dev/null 2>&1; then
  { command -v debootstrap >/dev/null || apt-get install -y -q debootstrap; } &&
    { [ -x "$chroot_dir/usr/bin/apt-get" ] && [ ! -d "$chroot_dir/debootstrap" ] || debootstrap --variant=minbase --include=ca-certificates trixie "$chroot_dir"; } &&
    cp /etc/resolv.conf "$chroot_dir/etc/resolv.conf" &&
    chroot "$chroot_dir" bash -c "apt-get update -q && DEBIAN_FRONTEND=noninteractive apt-get install -y -q \
      --no-install-recommends $packages" ||
    report "installing Blender ($packages) into $chroot_dir failed"
fi
[ -x "$chroot_dir/usr/bin/blender" ] || report "no Blender in $chroot_dir (/usr/bin/blender)"

mounted=()
cleanup() {
  for ((i = ${#mounted[@]} - 1; i >= 0; i--)); do  # a mount still busy: once more, then lazily
    umount -R "${mounted[i]}" 2>/dev/null || { sleep 1; umount -R "${mounted[i]}" 2>/dev/null; } ||
      umount -R -l "${mounted[i]}" || echo "could not unmount ${mounted[i]}" >&2
  done
}
trap cleanup EXIT
for fs in proc dev sys; do
  if ! mountpoint -q "$chroot_dir/$fs"; then
    if [ "$fs" = proc ]; then
      mount -t proc proc "$chroot_dir/proc"
    else  # rslave: unmounting the copy below must never propagate to the host's own mounts
      mount --rbind "/$fs" "$chroot_dir/$fs" && mount --make-rslave "$chroot_dir/$fs"
    fi
    mounted+=("$chroot_dir/$fs")
  fi
done

bash "$root/scripts/setup_venv.sh" >/dev/null || report "scripts/setup_venv.sh failed"
rm -rf "$work/dist"
"$root/.venv/bin/python" "$root/scripts/build_extension.py" --output-dir "$work/dist" --platforms linux-x64 >/dev/null ||
  report "building the extension zip failed (scripts/build_extension.py)"
zips=("$work"/dist/*linux_x64.zip)
[ -f "${zips[0]}" ] || report "scripts/build_extension.py wrote no *linux_x64.zip"
zip_name=$(basename "${zips[0]}")
rm -rf "$chroot_dir$inside" "$chroot_dir/root/.config/blender" "$work/shots" "$work/colour"
mkdir -p "$chroot_dir$inside/shots"
cp "$work/dist/$zip_name" "$root"/scripts/real_blender_{check,colour,embree,faults,shots}.py "$chroot_dir$inside/"

# The X screen every 0.3 s while Blender runs (the status bar shows the bake's progress text).
chroot "$chroot_dir" bash -c "cd $inside && (for i in \$(seq -w 1 150); do \
    import -display :99 -window root shots/screen_\$(date +%s.%N).png 2>/dev/null; sleep 0.3; \
    [ \$i -lt 20 ] || pgrep -x blender >/dev/null || break; done &) && \
  timeout 600 xvfb-run -n 99 -s '-screen 0 1600x1000x24 -ac' blender --factory-startup \
    --enable-event-simulate --python real_blender_check.py -- $inside/$zip_name $inside/result.json" \
  > "$work/blender.log" 2>&1 || true
sleep 1
cp -r "$chroot_dir$inside/shots" "$work/shots"
[ ! -d "$chroot_dir$inside/colour" ] || cp -r "$chroot_dir$inside/colour" "$work/colour"
if [ ! -f "$chroot_dir$inside/result.json" ]; then
  report "Blender wrote no result; its output is in $work/blender.log: $(tail -n 3 "$work/blender.log" | tr '\n' ' ')"
fi
cp "$chroot_dir$inside/result.json" "$work/result.json"
report
