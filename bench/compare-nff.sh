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
command -v povray >/dev/null || { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq povray >/dev/null; }
cargo build --release -q
work="$(mktemp -d)"; trap 'rm -rf "$work"' EXIT
python3 bench/nff2pov.py "$scene" > "$work/scene.pov"
whitted() {
    ./target/release/whitted render "$scene" --depth 5 --threads "$threads" --stats -q -o "$work/whitted.png" |
        awk '/^(load|build|render) time/ {s += $3} END {printf "%.4f\n", s}'
}
pov() {
    povray "$work/scene.pov" +W512 +H512 -D -A +WT"$threads" +FN +O"$work/povray.png" >"$work/log" 2>&1 ||
        { cat "$work/log" >&2; exit 1; }
    secs() { grep "$1 Time:" "$work/log" | sed -E 's/.*\(\s*([0-9.]+) seconds\).*/\1/' | head -1; }
    local parse bound trace
    parse=$(secs Parse); bound=$(secs Bounding); trace=$(secs Trace)
    python3 -c "print(f'{${parse:-0}+${bound:-0}+${trace:-0}:.4f}')"
}
for _ in $(seq "$rounds"); do whitted >> "$work/w"; pov >> "$work/p"; done
w=$(sort -g "$work/w" | head -1); p=$(sort -g "$work/p" | head -1)
python3 -c "print(f'$(basename "$scene"), $threads threads: Whitted {$w:.4f} s, POV-Ray {$p:.4f} s, ratio {$w / $p:.3f} (best of $rounds each)')"
