#!/bin/sh
# The MHP training and validation sets (held-out CMU subject 03), one worker each, at nice 10.
# Usage: scripts/make_mhp_sets.sh [MOTION_DIR] [OUT_ROOT] [TRAIN_MESHES] [VAL_MESHES]
# Resumable: run it again after a kill. ANNY_CACHE_DIR must point to anny's cache.
set -e
MOTION=${1:-/work/shared/data/cmu_mocap}
OUT=${2:-/work/data}
TRAIN=${3:-600}
VAL=${4:-100}
RMPL=${RMPL:-/work/venv-synth/bin/rmpl}
nice -n 10 "$RMPL" generate configs/mhp.toml --out "$OUT/mhp_val" --no-progress \
    --set poses="\"$MOTION\"" --set 'subjects=["03"]' --set 'exclude_subjects=[]' \
    --set num_meshes="$VAL" --set seed=101
nice -n 10 "$RMPL" generate configs/mhp.toml --out "$OUT/mhp_train" --no-progress \
    --set poses="\"$MOTION\"" --set 'exclude_subjects=["03"]' --set num_meshes="$TRAIN"
