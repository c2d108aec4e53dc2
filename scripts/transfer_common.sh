# Shared by scripts/transfer_ablation.sh, scripts/transfer_benchmark.sh, scripts/built_benchmark.sh,
# scripts/built_fewshot.sh and scripts/fewshot_study.sh (sourced, after ROOT, OUT, BIN and THREADS are set): the stationary ts4
# scene, the randomized preset, the switch that turns its structure pool off, the held-out
# families' settings (transfer_benchmark.sh describes them), and a resumable dataset generator.
TS4=(--config "$ROOT/configs/ts4.yaml" --set scene.stationary.z_grid_m=0)
RAND=(--config "$ROOT/configs/randomized.yaml")
# a family keeps the preset's strikers and sensor chain but has one structure of its own
ONE=(--set randomize.structure_variants=0 --set 'randomize.bolt_count=[]'
     --set 'randomize.bolt_z_jitter_m=[]' --set 'randomize.bolt_stiffness_scale=[]'
     --set 'randomize.flange_mount_scale=[]' --set 'randomize.tool_mount_scale=[]'
     --set 'randomize.poisson_ratio=[]' --set 'randomize.attached_mass_count=[]'
     --set 'randomize.attached_mass_kg=[]' --set 'randomize.disc_mass_kg=[]')

# A calibration set of structures beyond the pool (with RAND): configs/beyond.yaml widens every
# structure and placement range of the preset to 1.5x its width about its centre and draws a pool
# of 48 variants, under a seed of its own (7), so that its pool is not the training pool
# stretched. Its ranges stop short of every held-out family of transfer_benchmark.sh (mounts
# 0.089-11x against the families' 0.05x and 20x, E 0.78-1.23x against 0.7x, 1-6 bolts per seam
# against 7, mics +-3 mm and +-3 degrees against 4-5), so the families stay outside anything a
# model was fitted on.
BEYOND=(--seed 7 --config "$ROOT/configs/beyond.yaml")

# the config arguments of a held-out family (with RAND and ONE)
family_args() {
  case $1 in
    in) echo "" ;;
    bolts) echo "--set shell.bolt_z_m=[-0.13,-0.0867,-0.0433,0,0.0433,0.0867,0.13] --set shell.bolt_stiffness_n_m=6.0e6" ;;
    stiff) echo "--set shell.flange_mount_stiffness_n_m2=1.0e8 --set shell.tool_mount_stiffness_n_m2=2.0e7" ;;
    loose) echo "--set shell.flange_mount_stiffness_n_m2=2.5e5 --set shell.tool_mount_stiffness_n_m2=5.0e4" ;;
    modulus) echo "--set material.youngs_modulus_pa=2.1e9 --set randomize.youngs_modulus_scale=[] --set randomize.temperature_c=[]" ;;
    mics) echo "--set mics.z_m=[-0.1345,-0.1255,-0.1340,0.1255,0.1345,0.1260] --set mics.theta_deg=[4.5,115.5,244.5,-4.0,124.5,235.5] --set randomize.mic_z_offset_m=[] --set randomize.mic_theta_offset_deg=[]" ;;
    fine) echo "--set shell.axial_spacing_m=0.005 --set shell.dispersion=thin" ;;
    chain) echo "--set shell.bolt_model=tie --set daq.input_resistance_ohm=99500 --set randomize.highpass_hz=[] --set randomize.hum_hz=[50,50] --set randomize.hum_rms_v=[3.0e-3,3.0e-3] --set randomize.hum_harmonics=9" ;;
    halfspace) echo "--set acoustics.contact.wall=rigid" ;;
  esac
}

# the config arguments of an as-built family of scripts/built_benchmark.sh (after TS4; that script
# describes them)
BUILT=(--config "$ROOT/configs/built.yaml")
built_family_args() {
  case $1 in
    nominal) echo "" ;;
    in) echo "${RAND[*]} ${BUILT[*]}" ;;
    soft) echo "${RAND[*]} ${ONE[*]} --set randomize.soft_striker_fraction=1
      --set randomize.soft_striker_youngs_modulus_pa=[1.5e6,3.0e7]" ;;
    noisy) echo "${RAND[*]} ${ONE[*]} --set randomize.noise_floor_v=[]
      --set randomize.peak_to_noise_db=[18,26] --set randomize.highpass_hz=[200,400]
      --set randomize.highpass_order=[2,2] --set randomize.lowpass_hz=[5000,7000]
      --set randomize.lowpass_order=[2,2]" ;;
    built|solid) echo "${RAND[*]} ${ONE[*]} --set randomize.noise_floor_v=[]
      --set randomize.peak_to_noise_db=[30,45]
      --set randomize.soft_striker_fraction=0.2
      --set randomize.soft_striker_youngs_modulus_pa=[3.0e6,1.0e8]
      --set shell.bolt_z_m=[-0.121,0.013,0.087] --set shell.bolt_stiffness_scale=[0.05,1,8]
      --set shell.flange_mount_stiffness_n_m2=2.5e5 --set shell.tool_mount_stiffness_n_m2=2.0e7
      --set mics.z_m=[-0.1335,-0.1265,-0.1338,0.1263,0.1336,0.1268]
      --set mics.theta_deg=[3.5,116.5,244,-3.5,123.5,236.5]
      --set randomize.mic_z_offset_m=[] --set randomize.mic_theta_offset_deg=[]
      --set material.youngs_modulus_pa=2.28e9 --set randomize.youngs_modulus_scale=[]
      --set randomize.temperature_c=[]" ;;
    massed) echo "$(built_family_args built)
      --set shell.attached_mass_kg=[0.045,0.035,0.0031,0.0028,0.0034,0.0029,0.0033,0.003]
      --set shell.attached_mass_z_m=[-0.118,0.061,-0.1335,-0.1265,-0.1338,0.1263,0.1336,0.1268]
      --set shell.attached_mass_theta_deg=[175,-62,3.5,116.5,244,-3.5,123.5,236.5]" ;;
  esac
}

gen() {  # name first_index count config-args...: OUT/name.h5 unless it exists, with its wall time
  local name=$1 first=$2 count=$3; shift 3
  [ -f "$OUT/$name.h5" ] && return
  local start
  start=$(date +%s)
  "$BIN" "${TS4[@]}" "$@" --threads "$THREADS" -q generate --count "$count" \
    --first-index "$first" --out "$OUT/$name.h5" --json > "$OUT/$name.generate.json"
  echo $(( $(date +%s) - start )) > "$OUT/$name.generate_wall_s"
}

# `train --resume` for a run that was started (RUN.partial) or finished; nothing for a new one
# (train refuses to resume what does not exist)
resume_flag() {
  if [ -e "$1.partial" ] || [ -e "$1" ]; then echo --resume; fi
}
