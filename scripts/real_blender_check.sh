#!/usr/bin/env bash
# Runs the add-on in a real Blender program with a window, which the test suite (bpy as a module,
# headless) cannot: the modal bake through Blender's own event loop, undo and redo, Esc, and the
# shared-buffer Embree path inside a program that links its own Embree.
#
#   sudo bash scripts/real_blender_check.sh [WORK_DIR]     # default WORK_DIR: build/real-blender
#
# The Blender is Debian 13's package (Blender 4.3), installed with Xvfb into a debootstrap folder
# in WORK_DIR (~1.5 GB, about 2 minutes the first time, reused afterwards); the zip is built from
# this checkout (the .venv of scripts/setup_venv.sh). Needs root (debootstrap, chroot, mounts)
# and the Debian package registry. Not part of .ci/run. Prints one line per check, saves X
# screenshots of the run in WORK_DIR/shots and exits 1 if a check fails.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
work=$(mkdir -p "${1:-$root/build/real-blender}" && cd "${1:-$root/build/real-blender}" && pwd)
chroot_dir=$work/trixie
inside=/root/prt-check

if [ ! -x "$chroot_dir/usr/bin/blender" ]; then
  command -v debootstrap >/dev/null || apt-get install -y -q debootstrap
  debootstrap --variant=minbase --include=ca-certificates trixie "$chroot_dir"
  cp /etc/resolv.conf "$chroot_dir/etc/resolv.conf"
  chroot "$chroot_dir" bash -c "apt-get update -q && DEBIAN_FRONTEND=noninteractive apt-get install -y -q \
    --no-install-recommends blender xvfb xauth imagemagick"
fi

mounted=()
cleanup() {
  for ((i = ${#mounted[@]} - 1; i >= 0; i--)); do umount -R "${mounted[i]}" 2>/dev/null || true; done
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

bash "$root/scripts/setup_venv.sh" >/dev/null
rm -rf "$work/dist"
"$root/.venv/bin/python" "$root/scripts/build_extension.py" --output-dir "$work/dist" --platforms linux-x64 >/dev/null
zip_name=$(basename "$(ls "$work"/dist/*linux_x64.zip)")
rm -rf "$chroot_dir$inside" "$chroot_dir/root/.config/blender" "$work/shots"
mkdir -p "$chroot_dir$inside/shots"
cp "$work/dist/$zip_name" "$root/scripts/real_blender_check.py" "$chroot_dir$inside/"

# The X screen every 0.3 s while Blender runs (the status bar shows the bake's progress text).
chroot "$chroot_dir" bash -c "cd $inside && (for i in \$(seq -w 1 150); do \
    import -display :99 -window root shots/screen_\$(date +%s.%N).png 2>/dev/null; sleep 0.3; \
    [ \$i -lt 20 ] || pgrep -x blender >/dev/null || break; done &) && \
  timeout 600 xvfb-run -n 99 -s '-screen 0 1600x1000x24 -ac' blender --factory-startup \
    --enable-event-simulate --python real_blender_check.py -- $inside/$zip_name $inside/result.json" \
  > "$work/blender.log" 2>&1 || true
sleep 1
cp -r "$chroot_dir$inside/shots" "$work/shots"
if [ ! -f "$chroot_dir$inside/result.json" ]; then
  echo "Blender wrote no result; its output is in $work/blender.log" >&2
  exit 1
fi
cp "$chroot_dir$inside/result.json" "$work/result.json"
python3 - "$work" <<'EOF'
import glob, json, os, shutil, sys
work = sys.argv[1]
r = json.load(open(os.path.join(work, "result.json")))
log = open(os.path.join(work, "blender.log"), errors="replace").read()
r["checks"]["no Python traceback in Blender's output"] = "Traceback" not in log
# The screen 1 s after the display was turned on and after the lighting was turned.
shots = sorted((float(os.path.basename(p)[7:-4]), p) for p in glob.glob(os.path.join(work, "shots", "screen_*.png")))
for key, name in (("display_on_at", "display_on.png"), ("rotated_at", "display_rotated.png")):
    later = [p for t, p in shots if key in r and t >= r[key] + 1.0]
    if later:
        shutil.copy(later[0], os.path.join(work, name))
print(f"Blender {r['blender']} (Python {r['python']}); Embree bound from {r.get('binding_library')}")
for name, ok in r["checks"].items():
    print(("PASS  " if ok else "FAIL  ") + name)
if "exception" in r:
    print(r["exception"])
print(f"screenshots: {work}/display_on.png, {work}/display_rotated.png, {work}/shots/")
sys.exit(0 if all(r["checks"].values()) else 1)
EOF
