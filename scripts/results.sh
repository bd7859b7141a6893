#!/usr/bin/env bash
# Every evaluation behind docs/results.md, in order. Each writes results/<name>/ (results.md,
# CSVs, plots); re-running one command regenerates its table.
#
# Usage: scripts/results.sh SHARED_DATA BANK [RUNS]
#   SHARED_DATA: the folder holding shelf_dev/, fixtures/, pose2sim_demo/
#   BANK: the pose bank, `rmpl poses SHARED_DATA/cmu_mocap --out BANK`
#   RUNS: the training runs of scripts/ablations.sh (default runs/); MHP data in data/
#         (scripts/make_mhp_sets.sh, plus the occlusion sets below)
# Steps whose inputs are missing are skipped with a message.
set -uo pipefail
D=$1
BANK=$2
RUNS=${3:-runs}
S=$D/shelf_dev
mkdir -p results
E() { # name, then rmpl evaluate options
    local name=$1
    shift
    echo "== $name"
    rmpl evaluate "$@" --out "results/$name" > "results/$name.log" 2>&1 \
        || echo "   failed: see results/$name.log"
}
have() { for r in "$@"; do [ -e "$r" ] || { echo "== skipped: no $r"; return 1; }; done; }

# Shelf (real OpenPose detections): number of views, occlusion, calibration noise.
E shelf_views --dataset shelf --root "$S" --methods triangulate,robust,rmpl --views 1,2,3,4,5
E shelf_dropout --dataset shelf --root "$S" --methods triangulate,robust,rmpl --views all,pairs \
    --dropout 0,0.2,0.4,0.6
have "$RUNS/abl/base" "$RUNS/abl/calib_aug" && E shelf_calib --dataset shelf --root "$S" \
    --methods "triangulate,robust,rmpl,rmpl:$RUNS/abl/base,rmpl:$RUNS/abl/calib_aug" \
    --views all,pairs --calib-noise 2,20 --calib-reps 5

# The whole `rmpl run` chain on Shelf, scored against the ground truth.
for m in rmpl triangulate robust; do
    rmpl run --calib "$S/calibration.json" --keypoints "$S" --method "$m" \
        --out "results/shelf_e2e/$m" --no-pictures > /dev/null 2>&1
done
E shelf_e2e/eval --dataset shelf --root "$S" --poses results/shelf_e2e/rmpl/poses.npz \
    results/shelf_e2e/triangulate/poses.npz results/shelf_e2e/robust/poses.npz

# Synthetic scenes of held-out motion: view counts, camera geometry.
E synthetic_views --dataset synthetic --root "$BANK" --methods triangulate,robust,rmpl \
    --views 1,2,3,4,5
E sphere --dataset synthetic --root "$BANK" --methods triangulate,robust,rmpl --cameras sphere \
    --heights 2.2,3.2,4 --angles 10,20,30,40,50,60,70,80,90,100,110,120,130,140,150,160,170,180

# The small real fixtures (a few frames each: loader checks more than benchmarks).
E campus_fixture --dataset campus --root "$D/fixtures/campus" --methods triangulate,robust,rmpl \
    --views all
E panoptic_fixture --dataset panoptic --root "$D/fixtures/panoptic_body3d" \
    --methods triangulate,robust,rmpl --views all
E h36m_fixture --dataset h36m --root "$D/fixtures/h36m" --methods triangulate,robust,rmpl \
    --views all

# Trained variants (scripts/ablations.sh) on Shelf. Pixel-input models need the training
# rig, so they are compared on their synthetic validation only.
ABL=""
for r in base no_conf recenter_only literal mlp maxv2 maxv3 maxv8 drop04; do
    [ -e "$RUNS/abl/$r" ] && ABL="$ABL,rmpl:$RUNS/abl/$r"
done
[ -n "$ABL" ] && E shelf_ablations --dataset shelf --root "$S" --methods "triangulate$ABL" \
    --views 1,2,3,4,5
have "$RUNS/abl/base" "$RUNS/abl/drop04" && E shelf_dropout_training --dataset shelf \
    --root "$S" --methods "triangulate,rmpl:$RUNS/abl/base,rmpl:$RUNS/abl/drop04" \
    --views all,pairs --dropout 0,0.2,0.4,0.6
for p in "" _occ0.2 _occ0.4; do
    have "$RUNS/abl/drop04" "data/mhp_val$p" && E "drop_mhp_val$p" --dataset synthetic \
        --root "data/mhp_val$p" --methods "triangulate,robust,rmpl:$RUNS/abl/base,rmpl:$RUNS/abl/drop04" \
        --views 2,3,5 --samples 1000
done

# MHP: parametric noise vs MHP renders vs mixes, on held-out renders and on Shelf.
MHP=""
for r in B_parametric C_mhp D_mix E_fitted F_mix_fitted; do
    [ -e "$RUNS/mhp/$r" ] && MHP="$MHP,rmpl:$RUNS/mhp/$r"
done
if [ -n "$MHP" ]; then
    E shelf_mhp --dataset shelf --root "$S" --methods "triangulate,robust$MHP" --views 1,2,3,4,5
    for p in "" _occ0.2 _occ0.4; do
        have "data/mhp_val$p" && E "mhp_val$p" --dataset synthetic --root "data/mhp_val$p" \
            --methods "triangulate,robust,rmpl$MHP" --views 1,2,3,4,5 --samples 1000
    done
fi

# The larger MHP set, detector-model randomisation and robust ray intersections (600-step
# runs of scripts/ablations.sh), on Shelf, the held-out renders and two recordings scored by
# held-out views (no ground truth needed).
S4=""
for r in B_parametric D_mix C2_mhp D2_mix G_random H2_mix_random K_robust L2_mix_robust; do
    [ -e "$RUNS/mhp/$r" ] && S4="$S4,rmpl:$RUNS/mhp/$r"
done
if [ -n "$S4" ]; then
    E shelf_mhp2 --dataset shelf --root "$S" --methods "triangulate,robust$S4" --views 2,3,4,5
    have data/mhp_val && E mhp_val2 --dataset synthetic --root data/mhp_val \
        --methods "triangulate,robust,rmpl$S4" --views 2,3,4,5 --samples 1000
    P2S=$D/pose2sim_demo/Pose2Sim/S01_Demo_SingleTrial
    have "$P2S" && E rec_pose2sim --dataset recording --calib "$P2S/calibration/Calib.qca.txt" \
        --keypoints "$P2S"/pose/cam01_json "$P2S"/pose/cam02_json "$P2S"/pose/cam03_json \
        "$P2S"/pose/cam04_json --methods "triangulate,robust,rmpl$S4" --views 1,2,3
    E rec_shelf --dataset recording --calib "$S/calibration.json" --keypoints "$S" \
        --methods "triangulate,robust,rmpl$S4" --views 2,3,4
fi

# The presets at an equal budget of training time.
have "$RUNS/eq/small" "$RUNS/eq/paper" && E shelf_presets --dataset shelf --root "$S" \
    --methods "triangulate,rmpl:$RUNS/eq/small,rmpl:$RUNS/eq/paper" --views 1,2,3,4,5

# Candidates for the shipped model (docs/results.md, "The shipped model"): selected on the
# held-out MHP renders, reported on Shelf.
C=""
for r in default_mix default_mix_drop04; do [ -e "$RUNS/$r" ] && C="$C,rmpl:$RUNS/$r"; done
if [ -n "$C" ]; then
    E select_synth --dataset synthetic --root "$BANK" --methods "triangulate,rmpl$C" \
        --views 2,3,4,5 --samples 1000
    have data/mhp_val && E select_mhp_val --dataset synthetic --root data/mhp_val \
        --methods "triangulate,robust,rmpl$C" --views 2,3,4,5 --samples 1000
    E select_shelf --dataset shelf --root "$S" --methods "triangulate,robust,rmpl$C" \
        --views 2,3,4,5
fi

# The shipped recipe with keypoint removal 0.4 (a candidate): under dropout on Shelf, and on
# the held-out renders.
if [ -e "$RUNS/default_v2_drop04" ]; then
    E v2_drop04_dropout --dataset shelf --root "$S" \
        --methods "triangulate,robust,rmpl,rmpl:$RUNS/default_v2_drop04" --views all,pairs \
        --dropout 0,0.2,0.4,0.6
    have data/mhp_val && E v2_drop04_mhp_val --dataset synthetic --root data/mhp_val \
        --methods "triangulate,robust,rmpl,rmpl:$RUNS/default_v2_drop04" --views 2,3,4,5 \
        --samples 1000
fi

# The shipped recipe re-run on today's bank (provenance check).
if [ -e "$RUNS/default_today" ]; then
    E today_shelf --dataset shelf --root "$S" \
        --methods "triangulate,robust,rmpl,rmpl:$RUNS/default_today" --views 2,3,4,5
    have data/mhp_val && E today_mhp_val --dataset synthetic --root data/mhp_val \
        --methods "triangulate,robust,rmpl,rmpl:$RUNS/default_today" --views 2,5 --samples 1000
fi
