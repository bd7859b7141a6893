#!/usr/bin/env bash
# The thesis ablations (issue 5) and the preset comparison (issue 3), as trained for
# docs/results.md: every run is the base recipe with one change, at an equal, short budget
# (600 steps of 128 samples, one torch thread), validated on the same fixed batches of
# held-out CMU subject 03. Resumable: re-run after a kill.
# The base recipe is configs/default.toml as it was before robust ray intersections
# (model.robust_anchor=0, parametric noise only): the runs below pin it.
#
# Usage: scripts/ablations.sh POSE_BANK.npz RUNS_DIR [MHP_TRAIN MHP_VAL [MHP_TRAIN2]]
#   POSE_BANK: rmpl.synth.motion.save_pose_set(load_motion_dir(CMU_DIR, fps=10))
#   MHP_TRAIN / MHP_VAL: `scripts/make_mhp_sets.sh` output (optional: skips the MHP runs)
#   MHP_TRAIN2: the larger second MHP set (scripts/make_mhp_sets.sh's last step; optional)
# Then: python scripts/runs_table.py RUNS_DIR/abl/* ; python scripts/runs_table.py RUNS_DIR/mhp/*
set -euo pipefail
BANK=$1
RUNS=$2
MHP_TRAIN=${3:-}
MHP_VAL=${4:-}
MHP_TRAIN2=${5:-}
T() { # name, then --set overrides
    local name=$1
    shift
    rmpl train configs/default.toml --out "$RUNS/$name" --set poses="\"$BANK\"" \
        --set steps=600 --set batch_size=128 --set val_every=200 --set threads=1 \
        --set model.robust_anchor=0 --set 'mhp=[]' "$@"
}
T abl/base
T abl/no_conf --set model.confidence=false
T abl/recenter_only --set model.geometric=false
T abl/literal --set model.geometric=false --set model.recenter=false
T abl/maxv2 --set max_views=2
T abl/maxv3 --set max_views=3
T abl/maxv8 --set max_views=8
T abl/calib_aug --set sampler.calib_noise_deg=2.0 --set sampler.calib_noise_m=0.02
T abl/pixels --set 'model.inputs="pixels"' --set model.geometric=false --set model.recenter=false
T abl/pixels_calib --set 'model.inputs="pixels+calib"' --set model.geometric=false \
    --set model.recenter=false
T abl/mlp --set 'model.architecture="mlp"' --set model.geometric=false
T abl/drop04 --set sampler.drop_rate=0.4
if [ -n "$MHP_TRAIN" ]; then
    T mhp/B_parametric --set mhp_val="\"$MHP_VAL\""
    T mhp/C_mhp --set mhp_val="\"$MHP_VAL\"" --set mhp="[\"$MHP_TRAIN\"]"
    T mhp/D_mix --set mhp_val="\"$MHP_VAL\"" --set mhp="[\"$MHP_TRAIN\"]" --set mhp_weight=0.5
    # The parametric source with the detector noise fitted to the MHP renders, alone and mixed.
    [ -f "$MHP_TRAIN/noise.toml" ] || rmpl generate --stats "$MHP_TRAIN" > /dev/null
    T mhp/E_fitted --set mhp_val="\"$MHP_VAL\"" --set noise_file="\"$MHP_TRAIN/noise.toml\""
    T mhp/F_mix_fitted --set mhp_val="\"$MHP_VAL\"" --set mhp="[\"$MHP_TRAIN\"]" \
        --set mhp_weight=0.5 --set noise_file="\"$MHP_TRAIN/noise.toml\""
fi
if [ -n "$MHP_TRAIN2" ]; then
    # Both MHP sets together (4x the renders, 7x the meshes), and the detector model's
    # domain randomisation, alone and with the renders.
    BOTH="[\"$MHP_TRAIN\",\"$MHP_TRAIN2\"]"
    T mhp/C2_mhp --set mhp_val="\"$MHP_VAL\"" --set mhp="$BOTH"
    T mhp/D2_mix --set mhp_val="\"$MHP_VAL\"" --set mhp="$BOTH" --set mhp_weight=0.5
    T mhp/G_random --set mhp_val="\"$MHP_VAL\"" --set sampler.noise_randomize=1.0
    T mhp/H2_mix_random --set mhp_val="\"$MHP_VAL\"" --set mhp="$BOTH" --set mhp_weight=0.5 \
        --set sampler.noise_randomize=1.0
    # Ray intersections robust to an outlying view, alone and with the renders.
    T mhp/K_robust --set mhp_val="\"$MHP_VAL\"" --set model.robust_anchor=3
    T mhp/L2_mix_robust --set mhp_val="\"$MHP_VAL\"" --set mhp="$BOTH" --set mhp_weight=0.5 \
        --set model.robust_anchor=3
fi
# Presets at an equal budget of wall time (about 10 minutes each on one thread).
rmpl train configs/default.toml --out "$RUNS/eq/small" --set poses="\"$BANK\"" \
    --set model.robust_anchor=0 --set steps=700 --set batch_size=256 --set val_every=350 --set threads=1
rmpl train configs/paper.toml --out "$RUNS/eq/paper" --set poses="\"$BANK\"" \
    --set steps=250 --set batch_size=32 --set val_every=125 --set lr=3e-4 --set threads=1
# Full-length candidates for the shipped model (docs/results.md, "The shipped model").
if [ -n "$MHP_TRAIN" ]; then
    rmpl train configs/default.toml --out "$RUNS/default_mix" --set poses="\"$BANK\"" \
        --set mhp="[\"$MHP_TRAIN\"]" --set mhp_weight=0.5 --set mhp_val="\"$MHP_VAL\"" \
        --set steps=2500 --set threads=1 --set model.robust_anchor=0
    rmpl train configs/default.toml --out "$RUNS/default_mix_drop04" --set poses="\"$BANK\"" \
        --set mhp="[\"$MHP_TRAIN\"]" --set mhp_weight=0.5 --set mhp_val="\"$MHP_VAL\"" \
        --set steps=2500 --set sampler.drop_rate=0.4 --set threads=2 --set model.robust_anchor=0
fi
# The first shipped recipe re-run on today's bank (docs/results.md, provenance check).
rmpl train configs/default.toml --out "$RUNS/default_today" --set poses="\"$BANK\"" \
    --set steps=4500 --set model.robust_anchor=0 --set 'mhp=[]'
# The shipped model (session 4): configs/default.toml as it is, both MHP sets.
if [ -n "$MHP_TRAIN2" ]; then
    rmpl train configs/default.toml --out "$RUNS/default_v2" --set poses="\"$BANK\"" \
        --set "mhp=[\"$MHP_TRAIN\",\"$MHP_TRAIN2\"]" --set mhp_val="\"$MHP_VAL\""
    # The same with keypoint removal 0.4 (a candidate, not shipped).
    rmpl train configs/default.toml --out "$RUNS/default_v2_drop04" --set poses="\"$BANK\"" \
        --set "mhp=[\"$MHP_TRAIN\",\"$MHP_TRAIN2\"]" --set mhp_val="\"$MHP_VAL\"" \
        --set sampler.drop_rate=0.4
fi
