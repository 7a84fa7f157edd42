#!/usr/bin/env bash
# Times Whitted against POV-Ray 3.7 on any NFF scene, the way bench/compare.sh times the
# sphereflake: 512x512, depth 5 (POV-Ray's max_trace_level), Whitted's load + build +
# render against POV-Ray's parse + bounding + trace, the two programs alternating, best
# of ROUNDS each. The scene goes to POV-Ray through bench/nff2pov.py. Installs povray
# from Debian if missing.
# Usage: [ROUNDS=5] bench/compare-nff.sh SCENE.nff [THREADS]
set -euo pipefail
[ $# -ge 1 ] || { echo "usage: bench/compare-nff.sh SCENE.nff [THREADS]" >&2; exit 2; }
scene="$(realpath "$1")"; threads="${2:-2}"; rounds="${ROUNDS:-5}"
cd "$(dirname "$0")/.."
. bench/nff-timers.sh
command -v povray >/dev/null || { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq povray >/dev/null; }
cargo build --release -q
work="$(mktemp -d)"; trap 'rm -rf "$work"' EXIT
python3 bench/nff2pov.py "$scene" > "$work/scene.pov"
for _ in $(seq "$rounds"); do
    whitted_nff "$scene" "$threads" "$work/whitted.png" >> "$work/w"
    pov_nff "$work/scene.pov" "$threads" "$work/povray.png" >> "$work/p"
done
w=$(sort -g "$work/w" | head -1); p=$(sort -g "$work/p" | head -1)
python3 -c "print(f'$(basename "$scene"), $threads threads: Whitted {$w:.4f} s, POV-Ray {$p:.4f} s, ratio {$w / $p:.3f} (best of $rounds each)')"
