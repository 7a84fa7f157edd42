# Timers for an NFF scene, sourced by bench/compare.sh and bench/compare-nff.sh: each
# prints seconds, as the SPD rules time a scene (512x512, depth 5).
# whitted_nff SCENE.nff THREADS OUT.png: Whitted's load + build + render.
whitted_nff() {
    ./target/release/whitted render "$1" --depth 5 --threads "$2" --stats -q -o "$3" |
        awk '/^(load|build|render) time/ {s += $3} END {printf "%.4f\n", s}'
}
# pov_nff SCENE.pov THREADS OUT.png: POV-Ray 3.7's parse + bounding + trace (its
# start-up excluded), no anti-aliasing.
pov_nff() {
    local log parse bound trace
    log="$(mktemp)"
    povray "$1" +W512 +H512 -D -A +WT"$2" +FN +O"$3" >"$log" 2>&1 || { cat "$log" >&2; rm -f "$log"; return 1; }
    secs() { grep "$1 Time:" "$log" | sed -E 's/.*\(\s*([0-9.]+) seconds\).*/\1/' | head -1; }
    parse=$(secs Parse); bound=$(secs Bounding); trace=$(secs Trace)
    rm -f "$log"
    python3 -c "print(f'{${parse:-0}+${bound:-0}+${trace:-0}:.4f}')"
}
