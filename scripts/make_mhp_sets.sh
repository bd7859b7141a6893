#!/bin/sh
# The MHP training and validation sets (held-out CMU subject 03), one worker each, at nice 10.
# Then the held-out occlusion sets mhp_val_occ0.2 and mhp_val_occ0.4.
# Last, a larger second training set, mhp_train2: TRAIN2_MESHES meshes (default 3000) x 10
# views, seed 7, two workers.
# Usage: scripts/make_mhp_sets.sh [MOTION_DIR] [OUT_ROOT] [TRAIN_MESHES] [VAL_MESHES] [TRAIN2_MESHES]
# Resumable: run it again after a kill. ANNY_CACHE_DIR must point to anny's cache.
set -e
MOTION=${1:-../shared/data/cmu_mocap}
OUT=${2:-data}
TRAIN=${3:-600}
VAL=${4:-100}
TRAIN2=${5:-3000}
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
# More meshes for fewer views each: pose variety costs little, each view costs a render and
# a detection.
nice -n 10 "$RMPL" generate configs/mhp.toml --out "$OUT/mhp_train2" --no-progress --workers 2 \
    --set poses="\"$MOTION\"" --set 'exclude_subjects=["03"]' --set num_meshes="$TRAIN2" \
    --set views=10 --set seed=7
