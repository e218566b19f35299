#!/usr/bin/env bash
# The libFuzzer harness: every parser a user's file reaches (session manifests, scene files, presets, model
# files, frame images, .npy arrays, TUM lists, fisheye calibrations, saved rooms, a session's fisheye frames)
# and every subcommand's flags, built with clang-15, AddressSanitizer
# and UBSan in build-fuzz/ (apart from the normal build), seeded from the bundled files and ../shared/data.
#   tools/fuzz.sh                 every target for 30 s (CI runs --seconds 10)
#   tools/fuzz.sh --seconds 600   longer
#   tools/fuzz.sh --runs 100000 manifest_fuzz scene_fuzz
# Exits non-zero on the first crash, leak, sanitizer report or time-out (the reproducer is in build-fuzz/).
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=30
runs=0
targets=()
while [[ $# -gt 0 ]]; do
  case "$1" in
    --seconds) seconds="$2"; shift 2 ;;
    --runs) runs="$2"; seconds=0; shift 2 ;;
    *) targets+=("$1"); shift ;;
  esac
done
all=(manifest_fuzz session_fuzz scene_fuzz preset_fuzz model_fuzz image_fuzz npy_fuzz tum_fuzz fisheye_yaml_fuzz room_fuzz fisheye_fuzz flag_fuzz)
[[ ${#targets[@]} -eq 0 ]] && targets=("${all[@]}")

# The fuzzing toolchain (not needed by the normal build or the tests).
if ! command -v clang++-15 > /dev/null || [[ ! -d /usr/lib/llvm-15/lib/clang/15.0.6/lib/linux ]]; then
  SUDO=""
  [[ $(id -u) -ne 0 ]] && SUDO="sudo"
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends clang-15 libfuzzer-15-dev
fi
if [[ ! -f build-fuzz/build.ninja ]]; then
  CC=clang-15 CXX=clang++-15 cmake -S . -B build-fuzz -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DMRGI_FUZZ=ON \
    -DMRGI_BUILD_TESTS=OFF -DMRGI_BUILD_BENCHMARKS=OFF > /dev/null
fi
cmake --build build-fuzz --target "${targets[@]}"

# Seeds: the bundled files (targets whose first byte picks a mode get each seed with every prefix).
seeds=build-fuzz/seeds
rm -rf "$seeds"
mkdir -p "$seeds"/{manifest_fuzz,session_fuzz,scene_fuzz,preset_fuzz,model_fuzz,image_fuzz,npy_fuzz,tum_fuzz,fisheye_yaml_fuzz,room_fuzz,fisheye_fuzz,flag_fuzz}
i=0; for f in recordings/*/manifest.json; do cp "$f" "$seeds/manifest_fuzz/m$i.json"; i=$((i + 1)); done
cp recordings/scenes/*.json "$seeds/scene_fuzz/"
cp recordings/presets.json "$seeds/preset_fuzz/"
i=0
for f in recordings/models/* tests/data/reproducers/*.ply tests/data/reproducers/*.gltf; do
  for p in 0 1 2 3; do { printf "\\x0$p"; cat "$f"; } > "$seeds/model_fuzz/m$i-$p"; done
  i=$((i + 1))
done
for p in 0 1 2; do
  { printf "\\x0$p"; cat recordings/tabletop-pt/colour/000000.png; } > "$seeds/image_fuzz/colour-$p"
  { printf "\\x0$p"; cat recordings/tabletop-pt/depth/000000.png; } > "$seeds/image_fuzz/depth-$p"
done
# Small seeds of the other formats (fuzz/seeds/image: JPEG, progressive JPEG, BMP, PGM, TIFF, EXR), each read
# by every reader.
for f in fuzz/seeds/image/*; do
  for p in 0 1 2; do { printf "\\x0$p"; cat "$f"; } > "$seeds/image_fuzz/$(basename "$f")-$p"; done
done
python3 - "$seeds/npy_fuzz" <<'PY'
# Bare arrays (first byte 0) from the ViSP archives, and small archives (first byte 1) of a 4x3 uint16
# data.npy, stored and deflated.
import sys, zipfile, glob, io, struct
out = sys.argv[1]
for i, f in enumerate(sorted(glob.glob('../shared/data/rgbd-visp-apriltag/*.npz'))[:2]):
    with zipfile.ZipFile(f) as z:
        for n in z.namelist():
            data = z.read(n)
            if len(data) < 65536:
                open(f"{out}/a{i}-{n}", 'wb').write(b"\0" + data)
header = "{'descr': '<u2', 'fortran_order': False, 'shape': (3, 4), }"
header += " " * (63 - (10 + len(header)) % 64) + "\n"
npy = b"\x93NUMPY\x01\x00" + struct.pack("<H", len(header)) + header.encode() + struct.pack("<12H", *range(1000, 1012))
open(f"{out}/small.npy", 'wb').write(b"\0" + npy)
for name, method in (("stored", zipfile.ZIP_STORED), ("deflated", zipfile.ZIP_DEFLATED)):
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, 'w', method) as z:
        z.writestr("width.npy", npy)
        z.writestr("data.npy", npy)
    open(f"{out}/{name}.npz", 'wb').write(b"\1" + buf.getvalue())
PY
python3 - "$seeds/session_fuzz" <<'PY'
# The session reader's seeds: a manifest for 80x60 frames, a NUL, and the index of three frames (the target
# writes the images); also the index alone.
import sys, json
out = sys.argv[1]
m = json.load(open('recordings/tabletop-synth/manifest.json'))
m.pop('fisheye', None)
for k in ('colour', 'depth'):
    m[k].update(width=80, height=60, fx=65.6, fy=65.6, cx=39.5, cy=29.5)
lines = []
for i, l in enumerate(open('recordings/tabletop-synth/frames.jsonl').read().splitlines()[:3]):
    f = json.loads(l)
    f.pop('fisheye', None)
    f['colour'], f['depth'] = f"colour/{i:06d}.png", f"depth/{i:06d}.png"
    lines.append(json.dumps(f))
index = "\n".join(lines) + "\n"
open(f"{out}/with_manifest", 'w').write(json.dumps(m) + "\0" + index)
open(f"{out}/index_only", 'w').write(index)
PY
python3 - "$seeds/room_fuzz" <<'PY'
# A saved room: room.json, a NUL, room.ply (a binary tetrahedron with normals and colours as mrgi room
# writes them, and an ASCII one), and for version 2 a NUL, the appearance's length (4 bytes), room_appearance.npy
# (4 rows of 5 float32) and room_openings.npy (2 rows of 7 float32: cell, radiance, clipped).
import sys, json, struct
out = sys.argv[1]
meta = json.dumps({"format": "mrgi-room", "version": 1, "generated_by": "mrgi room", "mesh": "room.ply", "voxel_m": 0.02,
                   "trunc_m": 0.08, "max_blocks": 8192, "frames_integrated": 3, "frames_refused": 0, "session": "s"}).encode()
v = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)]
f = [(0, 1, 2), (0, 1, 3), (0, 2, 3), (1, 2, 3)]
head = ("ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty double x\nproperty double y\nproperty double z\n"
        "property double nx\nproperty double ny\nproperty double nz\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n"
        "element face 4\nproperty list uchar uint vertex_indices\nend_header\n").encode()
body = b"".join(struct.pack("<6d3B", *p, 0, 0, 1, 200, 100, 50) for p in v) + b"".join(struct.pack("<B3I", 3, *t) for t in f)
open(f"{out}/binary", 'wb').write(meta + b"\0" + head + body)
ascii_ = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nelement face 4\nproperty list uchar int vertex_indices\nend_header\n"
ascii_ += "".join("%d %d %d\n" % p for p in v) + "".join("3 %d %d %d\n" % t for t in f)
open(f"{out}/ascii", 'wb').write(meta + b"\0" + ascii_.encode())
meta2 = json.loads(meta)
meta2["version"] = 2
meta2["appearance"] = "room_appearance.npy"
hdr = "{'descr': '<f4', 'fortran_order': False, 'shape': (4, 5), }"
hdr += " " * ((64 - (10 + len(hdr) + 1) % 64) % 64) + "\n"
npy = b"\x93NUMPY\x01\x00" + struct.pack("<H", len(hdr)) + hdr.encode() + struct.pack("<20f", *([0.2, 0.1, 0.05, 3.0, 0.0] * 4))
open(f"{out}/binary_v2", 'wb').write(json.dumps(meta2).encode() + b"\0" + head + body + b"\0" + struct.pack("<I", len(npy)) + npy)
meta2["openings"] = {"cell_m": 0.1, "cells": "room_openings.npy"}
ohdr = "{'descr': '<f4', 'fortran_order': False, 'shape': (2, 7), }"
ohdr += " " * ((64 - (10 + len(ohdr) + 1) % 64) % 64) + "\n"
onpy = b"\x93NUMPY\x01\x00" + struct.pack("<H", len(ohdr)) + ohdr.encode() + struct.pack("<14f", 20, 3, 12, 0.4, 0.6, 0.9, 0, 21, 3, 12, 1, 1, 1, 1)
open(f"{out}/binary_v2_openings", 'wb').write(json.dumps(meta2).encode() + b"\0" + head + body + b"\0" + struct.pack("<I", len(npy)) + npy + onpy)
PY
printf '# timestamp filename\n1305031102.175304 rgb/1305031102.175304.png\n1305031102.211214 rgb/1305031102.211214.png\n' > "$seeds/tum_fuzz/rgb.txt"
printf '# timestamp tx ty tz qx qy qz qw\n1305031102.1758 1.3405 0.6266 1.6575 0.6574 0.6126 -0.2949 -0.3248\n' > "$seeds/tum_fuzz/groundtruth.txt"
cp ../shared/data/rgbd-open3d-iclnuim/trajectory.log "$seeds/tum_fuzz/" 2>/dev/null || true
cp ../shared/data/rgbd-open3d-iclnuim/camera.json "$seeds/tum_fuzz/" 2>/dev/null || true
cp ../shared/data/fisheye-ros-calib/ost.yaml "$seeds/fisheye_yaml_fuzz/" 2>/dev/null || true
# Fisheye frames: a 32x24 sky as half-float EXR, Radiance HDR and PNG, each under its own first byte.
{ printf '\x00'; cat fuzz/seeds/fisheye/sky.exr; } > "$seeds/fisheye_fuzz/exr"
{ printf '\x01'; cat fuzz/seeds/fisheye/sky.hdr; } > "$seeds/fisheye_fuzz/hdr"
{ printf '\x02'; cat fuzz/seeds/fisheye/sky.png; } > "$seeds/fisheye_fuzz/png"
{ printf '\x02'; cat fuzz/seeds/fisheye/sky.hdr; } > "$seeds/image_fuzz/sky.hdr-2"  # Radiance HDR through readAny
# Flags: one argv per subcommand (arguments separated by NUL bytes).
i=0
for argv in "replay|s|--out|o|--fps|30|--technique|dlpv|--pose|tracked|--mp4|" "insert|--session|s|--model|m.ply|--save|x.json|--albedo|0.5,0.5,0.5|--translate|0,0,0.1" \
            "room|s|--out|r|--voxel|0.02|--trunc|0.08|--max-depth|4" "room-lights|r|--at|0|0|0.06|--count|4" "lights|p.hdr|--exposure|1|--count|4" \
            "track|s|--json|--size|0.1|--hold|0.5|--decimate|2|--family|tag36h11|--id|3" "bench|--quick|--repeats|2|--ref-spp|8" \
            "record|--source|s|--out|o|--rate|30" "import-visp|d|--out|o|--tag-id|3" "synth|--out|o|--frames|3|--width|160|--height|120"; do
  printf '%s' "$argv" | tr '|' '\0' > "$seeds/flag_fuzz/a$i"
  i=$((i + 1))
done

export LSAN_OPTIONS="suppressions=$PWD/fuzz/lsan.supp:print_suppressions=0"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
[[ -x /usr/bin/llvm-symbolizer ]] && export ASAN_SYMBOLIZER_PATH=/usr/bin/llvm-symbolizer
# Two targets at a time (each fuzzer is one process on one core; CI has two): the same time per target.
fuzz_one() {
  local t=$1
  local corpus=build-fuzz/corpus/$t
  mkdir -p "$corpus" build-fuzz/crashes
  # Models: inputs up to 4 KB (small PLY/OBJ/glTF seeds): each run costs about 10 ms whatever its size, and
  # larger inputs only slow assimp's parsers down.
  local max_len=1048576
  [[ $t == model_fuzz ]] && max_len=4096
  local args=(-timeout=10 -rss_limit_mb=4096 -max_len=$max_len -artifact_prefix=build-fuzz/crashes/$t- -print_final_stats=1)
  if [[ $runs -gt 0 ]]; then args+=(-runs="$runs"); else args+=(-max_total_time="$seconds"); fi
  if ! build-fuzz/fuzz/$t "${args[@]}" "$corpus" "$seeds/$t" > build-fuzz/$t.log 2>&1; then
    { echo "$t: FAILED (see build-fuzz/$t.log)"; grep -m3 -E "ERROR|SUMMARY|==[0-9]+==" build-fuzz/$t.log || true; } > build-fuzz/$t.result
    return 1
  fi
  echo "$t: $(grep -m1 -E '^stat::number_of_executed_units' build-fuzz/$t.log | awk '{print $2}') executions, no crash" > build-fuzz/$t.result
}
status=0
running=0
for t in "${targets[@]}"; do
  if [[ $running -ge 2 ]]; then
    wait -n || status=1
    running=$((running - 1))
  fi
  fuzz_one "$t" &
  running=$((running + 1))
done
while [[ $running -gt 0 ]]; do
  wait -n || status=1
  running=$((running - 1))
done
for t in "${targets[@]}"; do cat build-fuzz/$t.result; done
exit $status
