#!/usr/bin/env bash
# Per-stage GPU milliseconds of every technique at 640x480 and 1920x1080 (the real-time section's device
# check): replays the bundled tabletop-synth session and a 1920x1080 ray-cast synth of the same room, one
# technique at a time, one stage after another (--sequential), and tabulates the profiler's GPU times (mean
# over the frames after the first). Usage:
#   tools/gpu-timings.sh OUT_DIR [--gl egl|osmesa] [--frames N] [--mrgi PATH] [--technique T]...
# Writes OUT_DIR/gpu_timings.json and OUT_DIR/gpu_timings.md and prints the table.
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:?usage: tools/gpu-timings.sh OUT_DIR [--gl egl|osmesa] [--frames N] [--mrgi PATH] [--technique T]...}
shift
gl=egl frames=8 mrgi=build/app/mrgi techniques=()
while (($#)); do
  case $1 in
    --gl) gl=$2; shift 2 ;;
    --frames) frames=$2; shift 2 ;;
    --mrgi) mrgi=$2; shift 2 ;;
    --technique) techniques+=("$2"); shift 2 ;;
    *) echo "tools/gpu-timings.sh: unknown option $1" >&2; exit 2 ;;
  esac
done
((${#techniques[@]})) || techniques=(dlpv kinect-val imperfect-volumes splatting pic dlpv+kinect-val)
mkdir -p "$out"
hd="$out/session-1080p"
if [[ ! -f $hd/manifest.json ]]; then
  rm -rf "$hd"
  "$mrgi" synth --out "$hd" --frames "$frames" --width 1920 --height 1080 --render raycast > "$out/synth.log" 2>&1
fi
for res in 640x480 1920x1080; do
  session=recordings/tabletop-synth
  [[ $res == 1920x1080 ]] && session=$hd
  for t in "${techniques[@]}"; do
    run="$out/$res-${t//+/_}"
    rm -rf "$run"
    "$mrgi" replay "$session" --out "$run" --gl "$gl" --scene recordings/scenes/tabletop.json --technique "$t" \
      --frames "$frames" --sequential > "$run.log" 2>&1 || { echo "$res $t failed: $(tail -n 1 "$run.log")" >&2; continue; }
  done
done
python3 - "$out" "${techniques[@]}" <<'EOF'
import json, os, sys
out, techniques = sys.argv[1], sys.argv[2:]
table, rows = {}, []
for res in ("640x480", "1920x1080"):
    for t in techniques:
        path = os.path.join(out, f"{res}-{t.replace('+', '_')}", "summary.json")
        if not os.path.exists(path):
            continue
        s = json.load(open(path))
        frames = s["per_frame"][1:] or s["per_frame"]
        stages = {}
        for f in frames:
            for name, ms in f.get("stages", {}).items():
                if isinstance(ms, dict) and ms.get("gpu_ms", 0) > 0:
                    stages[name] = stages.get(name, 0) + ms["gpu_ms"] / len(frames)
        gpu = sum(stages.values())
        table.setdefault(res, {})[t] = {"gpu_ms_total": gpu, "gpu_ms": stages, "device": s["gl"].get("renderer"),
                                        "wall_ms_per_frame": s.get("wall_ms_per_frame")}
        top = ", ".join(f"{k} {v:.2f}" for k, v in sorted(stages.items(), key=lambda kv: -kv[1])[:6])
        rows.append(f"| {res} | {t} | {gpu:.2f} | {s.get('wall_ms_per_frame', 0):.1f} | {top} |")
md = ["| resolution | technique | GPU ms a frame | wall ms a frame | largest GPU stages (ms) |", "|---|---|---:|---:|---|"] + rows
open(os.path.join(out, "gpu_timings.json"), "w").write(json.dumps(table, indent=1))
open(os.path.join(out, "gpu_timings.md"), "w").write("\n".join(md) + "\n")
print("\n".join(md))
EOF
