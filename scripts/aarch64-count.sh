#!/usr/bin/env bash
# Guest instructions of the aarch64 build on the shared scenes, under qemu-user with the counting
# plugin (scripts/qemu-insn-count.c): instruction counts, not time (there is no ARM machine here).
# Usage: scripts/aarch64-count.sh AARCH64_BINARY OUT_DIR [LEVEL=neon] [stereo-depth flags...]
# Writes OUT_DIR/<scene>.pfm and OUT_DIR/<scene>.counts, prints each scene's total (millions);
# PROFILE=1 also prints each scene's functions by instructions (aarch64-linux-gnu-nm).
# Needs qemu-user and gcc-aarch64-linux-gnu (.ci/aarch64-neon installs them). --threads 1.
set -euo pipefail
ROOT="$(cd "$(dirname "$0")/.." && pwd)"
bin="$(realpath "$1")"; out="$2"; level="${3:-neon}"; shift 3 || shift $#
data="${DATA:-$ROOT/../shared/data}"
plugin="$out/qemu-insn-count.so"
mkdir -p "$out"
gcc -shared -fPIC -O2 -o "$plugin" "$ROOT/scripts/qemu-insn-count.c" -Wl,--unresolved-symbols=ignore-all
tail -n +2 "$data/scenes.tsv" | while IFS=$'\t' read -r scene left right _ _ _ _ _ _ _ _ ndisp; do
  STEREO_DISPARITY_SIMD="$level" TBCOUNT_OUT="$out/$scene.counts" \
    qemu-aarch64 -L /usr/aarch64-linux-gnu -plugin "$plugin" "$bin" "$data/$scene/$left" \
    "$data/$scene/$right" --max-disparity "$ndisp" --disparity "$out/$scene.pfm" --quiet --threads 1 "$@" >/dev/null
  python3 - "$bin" "$out/$scene.counts" "$scene" "${PROFILE:-}" <<'PYEOF'
import bisect, collections, subprocess, sys
binary, counts, scene, profile = sys.argv[1:5]
rows, total = [], 0
for line in open(counts):
    p = line.split()
    if p[0] == "total":
        total = int(p[1])
    else:
        rows.append((int(p[0], 16), int(p[1]) * int(p[2])))
print(f"{scene}\t{total / 1e6:.1f} M instructions")
if profile:
    nm = subprocess.run(["aarch64-linux-gnu-nm", "-n", "-C", "--defined-only", binary], capture_output=True, text=True).stdout
    syms = [(int(a, 16), n) for a, t, n in (l.split(" ", 2) for l in nm.splitlines() if l.count(" ") >= 2) if t in "tTwW"]
    starts = [a for a, _ in syms]
    base = 0x5500000000  # where qemu-user loads a position-independent aarch64 executable
    by = collections.Counter()
    for va, n in rows:
        i = bisect.bisect_right(starts, va - base) - 1
        by[syms[i][1][:100] if i >= 0 and va >= base else "(shared libraries)"] += n
    for name, n in by.most_common(8):
        print(f"  {100 * n / total:5.1f} %  {name}")
PYEOF
done
