#!/usr/bin/env bash
# Measures Whitted against POV-Ray 3.7 (the seed room) and Intel Embree (the 1M-triangle
# displaced cube-sphere and a cloud of 10^6 spheres, same rays) alternately on this
# machine, with the sphereflake and a mixed NFF scene against POV-Ray too, prints the ratios that issues 7 and 21 track, and appends the figures as JSON lines
# to bench/results/DATE.jsonl. Installs povray and libembree-dev from Debian if missing.
# Usage: WHITTED_TOOLS=DIR [ROUNDS=3] [ROOM_ROUNDS=3] bench/compare.sh [THREADS] [--big]
# WHITTED_TOOLS is the folder holding the comparison harnesses (embree-bench/build.sh,
# povray-room/run.sh), which are not part of this repository (docs/performance.md).   (default 2
# threads, about six minutes; --big adds the 10M-triangle cube-sphere to each round,
# about three minutes more)
set -euo pipefail
cd "$(dirname "$0")/.."
threads=2; big=0
for a in "$@"; do case "$a" in --big) big=1 ;; *) threads="$a" ;; esac; done
tools="${WHITTED_TOOLS:-}"
if [ -z "$tools" ] || [ ! -f "$tools/embree-bench/build.sh" ] || [ ! -f "$tools/povray-room/run.sh" ]; then
    echo "bench/compare.sh: set WHITTED_TOOLS to the folder holding embree-bench/build.sh and" >&2
    echo "povray-room/run.sh (the comparison harnesses; see docs/performance.md)" >&2
    exit 2
fi
cpu="$(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ *//')"
date="$(date -u +%Y-%m-%dT%H:%M:%SZ)"
out="bench/results/$(date -u +%Y-%m-%d).jsonl"
mkdir -p target bench/results

cargo build --release -q
[ -x target/embree_bench ] || bash "$tools/embree-bench/build.sh" target/embree_bench >/dev/null

rounds="${ROUNDS:-3}"
# The room renders are short (a tenth of a second and less) and so at the mercy of the
# host's other load, which comes in spells of minutes: they get batches of
# $room_rounds rounds spread over the whole run (before each round of the meshes and after
# the last), still alternating and the same for both.
room_rounds="${ROOM_ROUNDS:-3}"
room_batches=0
room_batch() {
    for _ in $(seq "$room_rounds"); do
        whitted_room 1 >> target/room-w1; pov_room noaa >> target/room-p1
        whitted_room 4 >> target/room-w4; pov_room aa >> target/room-p5
        whitted_flake >> target/flake-w; pov_flake >> target/flake-p
        whitted_nff target/mixed.nff "$threads" target/compare-mixed.png >> target/mixed-w
        pov_nff target/mixed.pov "$threads" target/povray-mixed.png >> target/mixed-p
    done
    room_batches=$((room_batches + 1))
}
best() { sort -g | head -1; }
whitted_room() { # spp -> render time in seconds
    ./target/release/whitted render --threads "$threads" --spp "$1" --stats -q -o target/compare-room.png |
        sed -n 's/^render time *\([0-9.]*\) s/\1/p'
}
pov_room() { # mode -> POV-Ray trace time in seconds
    bash "$tools/povray-room/run.sh" "$1" "$threads" target/povray-room.png | sed -E 's/.*trace_s=([0-9.]+).*/\1/'
}

# The sphereflake (SPD "balls", level 4: 7,382 primitives) as the SPD rules time it:
# 512x512, depth 5, Whitted's load + build + render against POV-Ray's parse + bounding
# + trace.
whitted_flake() {
    ./target/release/whitted render target/balls.nff --depth 5 --threads "$threads" --stats -q -o target/compare-flake.png |
        awk '/^(load|build|render) time/ {s += $3} END {printf "%.4f\n", s}'
}
pov_flake() {
    bash "$tools/povray-spd/run.sh" "$threads" target/povray-sphereflake.png | sed -E 's/.*total_s=([0-9.]+).*/\1/'
}
./target/release/whitted generate sphereflake --level 4 -o target/balls.nff
# A scene of thousands of mixed primitives (a mesh among spheres, cylinders, cones and
# glass), timed the same way; POV-Ray reads it through bench/nff2pov.py.
. bench/nff-timers.sh
python3 bench/mixed_nff.py > target/mixed.nff
python3 bench/nff2pov.py target/mixed.nff > target/mixed.pov

# The machine is shared and its second core comes and goes, so each program runs once a
# round, alternating, for the room's rounds and $rounds rounds of the rest, and each keeps
# its best figure.
echo "CPU: $cpu; $threads threads; $rounds rounds, the room in batches of $room_rounds; $(uptime | sed 's/.*load/load/')"
for f in room-w1 room-p1 room-w4 room-p5 flake-w flake-p mixed-w mixed-p embree-1M.txt whitted-1M.jsonl embree-cloud.txt whitted-cloud.jsonl \
    embree-10M.txt whitted-10M.jsonl; do : > "target/$f"; done
for _ in $(seq "$rounds"); do
    room_batch
    ./target/embree_bench --gen-cubesphere 289 --name cubesphere-1M --quality high --runs 5 --no-packets >> target/embree-1M.txt
    ./target/release/whitted bench --scene cubesphere-1M --threads "$threads" --runs 5 --json >> target/whitted-1M.jsonl
    ./target/embree_bench --spheres 1000000 --name sphere-cloud-1M --quality high --runs 5 --no-packets >> target/embree-cloud.txt
    ./target/release/whitted bench --scene sphere-cloud-1M --threads "$threads" --runs 5 --json >> target/whitted-cloud.jsonl
    if [ "$big" = 1 ]; then
        # Its rays miss the caches, so the neighbours' memory traffic shows through the
        # CPU-seconds: it alternates too.
        ./target/embree_bench --gen-cubesphere 913 --name cubesphere-10M --quality high --runs 3 --no-packets >> target/embree-10M.txt
        ./target/release/whitted bench --scene cubesphere-10M --threads "$threads" --runs 3 --json >> target/whitted-10M.jsonl
    fi
done
room_batch
w1=$(best < target/room-w1); p1=$(best < target/room-p1); w4=$(best < target/room-w4); p5=$(best < target/room-p5)
fw=$(best < target/flake-w); fp=$(best < target/flake-p)
mw=$(best < target/mixed-w); mp=$(best < target/mixed-p)

commit="$(git rev-parse --short HEAD 2>/dev/null || echo unknown)$(git diff --quiet HEAD 2>/dev/null || echo +changes)"
python3 - "$w1" "$p1" "$w4" "$p5" "$cpu" "$date" "$threads" "$out" "$commit" "$((room_rounds * room_batches))" "$fw" "$fp" "$mw" "$mp" <<'PY'
import json, re, sys
w1, p1, w4, p5 = map(float, sys.argv[1:5])
cpu, date, threads, out, commit = sys.argv[5], sys.argv[6], int(sys.argv[7]), sys.argv[8], sys.argv[9]
room_rounds = int(sys.argv[10])
fw, fp, mw, mp = map(float, sys.argv[11:15])
# Every room figure, in the order taken, to show the spread behind the best ones.
room_samples = {k: [float(x) for x in open(f"target/room-{k}").read().split()] for k in ("w1", "p1", "w4", "p5")}
for scene in ("flake", "mixed"):
    room_samples.update({f"{scene}_{k}": [float(x) for x in open(f"target/{scene}-{k}").read().split()] for k in ("w", "p")})
def embree(path):
    """Embree's best figures over the rounds: highest rates, shortest build."""
    emb = {}
    for line in open(path):
        if not line.startswith("RESULT"):
            continue
        f = dict(kv.split("=", 1) for kv in line.split()[1:] if "=" in kv)
        if f["case"] == "build":
            emb["build_s"] = min(emb.get("build_s", float("inf")), float(f["best_s"]))
            emb["bytes"] = float(f["persistent_B_per_prim"])
        elif int(f.get("threads", 0)) == threads:
            emb[f["case"]] = max(emb.get(f["case"], 0.0), float(f["Mrays_per_cpu_s"]))
    return emb

def mesh_rows(label, emb, w):
    return [
        (f"{label} primary Mrays/CPU-s vs rtcIntersect1 (target >= 1.2)", w["primary_mrays_per_cpu_s"] / emb["primary_rtcIntersect1"],
         f'{w["primary_mrays_per_cpu_s"]:.2f} / {emb["primary_rtcIntersect1"]:.2f}'),
        (f"{label} shadow Mrays/CPU-s vs rtcOccluded1 (target >= 1.0)", w["shadow_mrays_per_cpu_s"] / emb["shadow_rtcOccluded1"],
         f'{w["shadow_mrays_per_cpu_s"]:.2f} / {emb["shadow_rtcOccluded1"]:.2f}'),
        (f"{label} incoherent Mrays/CPU-s vs rtcIntersect1 (target >= 0.9)", w["incoherent_mrays_per_cpu_s"] / emb["incoherent_rtcIntersect1"],
         f'{w["incoherent_mrays_per_cpu_s"]:.2f} / {emb["incoherent_rtcIntersect1"]:.2f}'),
        (f"{label} BVH build time vs Embree high quality (target <= 1.5)", w["build_ms"] / 1000 / emb["build_s"], f'{w["build_ms"]/1000:.3f} s / {emb["build_s"]:.3f} s'),
        (f"{label} acceleration bytes per triangle (target <= 64)", w["bytes_per_primitive"], f'Embree {emb["bytes"]:.1f}'),
    ]

def whitted(path):
    """Whitted's best figures over the rounds, likewise."""
    rows = [json.loads(l) for l in open(path) if l.strip()]
    if not rows:
        return None
    w = dict(rows[0])
    for r in rows[1:]:
        for k, v in r.items():
            if k.endswith("_mrays") or k.endswith("_per_cpu_s"):
                w[k] = max(w[k], v)
            elif k in ("build_ms", "build_cpu_s", "frame_ms"):
                w[k] = min(w[k], v)
    w["rounds"] = len(rows)
    return w

emb, w = embree("target/embree-1M.txt"), whitted("target/whitted-1M.jsonl")
emb_cloud, w_cloud = embree("target/embree-cloud.txt"), whitted("target/whitted-cloud.jsonl")
rows = [
    ("room 1 spp: Whitted render / POV-Ray trace (target <= 0.1)", w1 / p1, f"{w1:.4f} s / {p1:.3f} s"),
    ("room AA: Whitted 4 spp / POV-Ray 5 rays (target <= 0.1)", w4 / p5, f"{w4:.4f} s / {p5:.3f} s"),
    ("sphereflake: Whitted load+build+render / POV-Ray (target <= 0.12)", fw / fp, f"{fw:.4f} s / {fp:.3f} s"),
    ("mixed scene (mixed_nff.py): Whitted / POV-Ray (target <= 0.12)", mw / mp, f"{mw:.4f} s / {mp:.3f} s"),
] + mesh_rows("1M", emb, w) + [
    ("sphere cloud 1M primary Mrays/CPU-s vs Embree (target >= 1.0)",
     w_cloud["primary_mrays_per_cpu_s"] / emb_cloud["primary_rtcIntersect1"],
     f'{w_cloud["primary_mrays_per_cpu_s"]:.3f} / {emb_cloud["primary_rtcIntersect1"]:.3f}'),
]
emb10, w10 = (embree("target/embree-10M.txt"), whitted("target/whitted-10M.jsonl"))
if w10:
    rows += mesh_rows("10M", emb10, w10)
for name, ratio, detail in rows:
    print(f"{name:<66} {ratio:8.3f}   ({detail})")
with open(out, "a") as f:
    record = {"date": date, "commit": commit, "cpu": cpu, "threads": threads, "room_rounds": room_rounds,
              "room_spp1_s": w1, "povray_noaa_s": p1, "room_spp4_s": w4,
              "povray_aa_s": p5, "sphereflake_s": fw, "povray_sphereflake_s": fp, "mixed_s": mw, "povray_mixed_s": mp, "room_samples_s": room_samples, "embree": emb, "whitted": w, "embree_cloud": emb_cloud, "whitted_cloud": w_cloud,
              "embree_10M": emb10 or None, "whitted_10M": w10, "ratios": {n: r for n, r, _ in rows}}
    f.write(json.dumps(record) + "\n")
print(f"appended to {out}")
PY
