# Shared by scripts/transfer_ablation.sh and scripts/transfer_benchmark.sh (sourced, after ROOT,
# OUT, BIN and THREADS are set): the stationary ts4 scene, the randomized preset, the switch that
# turns its structure pool off, and a resumable dataset generator.
TS4=(--config "$ROOT/configs/ts4.yaml" --set scene.stationary.z_grid_m=0)
RAND=(--config "$ROOT/configs/randomized.yaml")
# a family keeps the preset's strikers and sensor chain but has one structure of its own
ONE=(--set randomize.structure_variants=0 --set 'randomize.bolt_count=[]'
     --set 'randomize.bolt_z_jitter_m=[]' --set 'randomize.bolt_stiffness_scale=[]'
     --set 'randomize.flange_mount_scale=[]' --set 'randomize.tool_mount_scale=[]'
     --set 'randomize.poisson_ratio=[]')

gen() {  # name first_index count config-args...: OUT/name.h5 unless it exists, with its wall time
  local name=$1 first=$2 count=$3; shift 3
  [ -f "$OUT/$name.h5" ] && return
  local start
  start=$(date +%s)
  "$BIN" "${TS4[@]}" "$@" --threads "$THREADS" -q generate --count "$count" \
    --first-index "$first" --out "$OUT/$name.h5" --json > "$OUT/$name.generate.json"
  echo $(( $(date +%s) - start )) > "$OUT/$name.generate_wall_s"
}
