#!/usr/bin/env bash
# The real-time targets measured side by side (docs/real-time.md): a baseline mrgi and this one, alternately, over
# R rounds, on the bundled tabletop-synth and tabletop-scan with recordings/scenes/tabletop.json, 20 frames, for
# --preset fast, --preset balanced and the default job. Replay by default (ms a frame and median latency from each
# summary.json); with --live the live window under Xvfb instead (its summary's wall_ms_per_frame). Every run has
# OMP_WAIT_POLICY and GLIBC_TUNABLES unset, as a user's shell has them. Usage:
#   tools/targets.sh --base PATH [--base-presets FILE] [--mrgi PATH] [--rounds R] [--live] [--session NAME]...
#     --base          the baseline binary (e.g. one built from an older tree)
#     --base-presets  the presets file the baseline's --preset reads (its own tree's recordings/presets.json)
# Prints one line a run, then per session and job the ms a frame of each binary and the speed-up (baseline's sum
# over this one's). Writes nothing but its runs' folders under a temporary directory, removed at the end.
set -euo pipefail
cd "$(dirname "$0")/.."
base="" basePresets="" mrgi=build/app/mrgi rounds=2 live=0 sessions=()
while (($#)); do
  case $1 in
    --base) base=$2; shift 2 ;;
    --base-presets) basePresets=$2; shift 2 ;;
    --mrgi) mrgi=$2; shift 2 ;;
    --rounds) rounds=$2; shift 2 ;;
    --live) live=1; shift ;;
    --session) sessions+=("$2"); shift 2 ;;
    *) echo "tools/targets.sh: unknown option $1" >&2; exit 2 ;;
  esac
done
[[ -n "$base" ]] || { echo "tools/targets.sh: --base PATH is required (the baseline mrgi)" >&2; exit 2; }
for b in "$base" "$mrgi"; do [[ -x "$b" ]] || { echo "tools/targets.sh: $b: not an executable" >&2; exit 2; }; done
[[ ${#sessions[@]} -eq 0 ]] && sessions=(tabletop-synth tabletop-scan)
if [[ $live -eq 1 ]] && ! command -v xvfb-run > /dev/null; then
  echo "tools/targets.sh: --live needs xvfb-run" >&2
  exit 2
fi
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
results="$work/results.txt"
for r in $(seq "$rounds"); do
  for s in "${sessions[@]}"; do
    for job in fast balanced default; do
      for which in base new; do
        bin=$mrgi args=(--scene recordings/scenes/tabletop.json)
        [[ $which == base ]] && bin=$base
        [[ $job != default ]] && args+=(--preset "$job")
        [[ $which == base && -n "$basePresets" ]] && args+=(--presets "$basePresets")
        if [[ $live -eq 1 ]]; then
          line=$(xvfb-run -a -s "-screen 0 1280x800x24" env -u GLIBC_TUNABLES -u OMP_WAIT_POLICY "$bin" live \
                   --source "recordings/$s" --frames 20 --no-loop "${args[@]}" 2> /dev/null | grep '^{' | tail -1)
          ms=$(python3 -c 'import json, sys; print("%.1f" % json.loads(sys.argv[1])["wall_ms_per_frame"])' "$line")
          latency=-
        else
          out="$work/$s-$job-$which-$r"
          env -u GLIBC_TUNABLES -u OMP_WAIT_POLICY "$bin" replay "recordings/$s" --out "$out" --frames 20 --mp4 "" \
            "${args[@]}" > /dev/null 2>&1
          read -r ms latency < <(python3 -c 'import json, sys
d = json.load(open(sys.argv[1]))
print("%.1f %.1f" % (d["wall_ms_per_frame"], d["latency_ms"]["median"]))' "$out/summary.json")
          rm -rf "$out"
        fi
        echo "$s $job $which round $r: $ms ms a frame, median latency $latency ms"
        echo "$s $job $which $ms" >> "$results"
      done
    done
  done
done
python3 - "$results" <<'PY'
import collections, sys
runs = collections.defaultdict(list)
for line in open(sys.argv[1]):
    session, job, which, ms = line.split()
    runs[(session, job, which)].append(float(ms))
print("\n| session | job | baseline ms | this ms | speed-up |\n|---|---|---|---|---|")
for (session, job, which), ms in runs.items():
    if which != "base":
        continue
    new = runs[(session, job, "new")]
    print("| %s | %s | %s | %s | %.2fx |" % (session, job, ", ".join("%.0f" % m for m in ms),
                                             ", ".join("%.0f" % m for m in new), sum(ms) / sum(new)))
PY
