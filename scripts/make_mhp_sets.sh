#!/bin/sh
# The MHP training and validation sets (held-out CMU subject 03), one worker each, at nice 10.
# Then the held-out occlusion sets mhp_val_occ0.2 and mhp_val_occ0.4.
# Usage: scripts/make_mhp_sets.sh [MOTION_DIR] [OUT_ROOT] [TRAIN_MESHES] [VAL_MESHES]
# Resumable: run it again after a kill. ANNY_CACHE_DIR must point to anny's cache.
set -e
MOTION=${1:-../shared/data/cmu_mocap}
OUT=${2:-data}
TRAIN=${3:-600}
VAL=${4:-100}
RMPL=${RMPL:-rmpl}
nice -n 10 "$RMPL" generate configs/mhp.toml --out "$OUT/mhp_val" --no-progress \
    --set poses="\"$MOTION\"" --set 'subjects=["03"]' --set 'exclude_subjects=[]' \
    --set num_meshes="$VAL" --set seed=101
nice -n 10 "$RMPL" generate configs/mhp.toml --out "$OUT/mhp_train" --no-progress \
    --set poses="\"$MOTION\"" --set 'exclude_subjects=["03"]' --set num_meshes="$TRAIN"
# The occlusion experiment (thesis 6.11.1): the same held-out meshes and cameras (seed 101)
# with black 50 px squares over joints before detection.
for p in 0.2 0.4; do
    nice -n 10 "$RMPL" generate configs/mhp.toml --out "$OUT/mhp_val_occ$p" --no-progress \
        --set poses="\"$MOTION\"" --set 'subjects=["03"]' --set 'exclude_subjects=[]' \
        --set num_meshes="$VAL" --set seed=101 --set occlusion_rate=$p
done
