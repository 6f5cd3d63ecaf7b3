#!/usr/bin/env bash
# Issue 5 experiment: the tiny gesture model (joint training, the paper's model) and its three ablations
# (disjoint training, no motion prior, no audio disentanglement) on the default synthetic corpus, on this
# CPU, scored with the evaluation suite on held-out texts (paper Table 1 layout plus the prior's
# reconstruction error, emotion edits and a 65-s long-audio seam check).
# Needs the speech model of experiments/speech_disentanglement.sh and the extractor of
# experiments/gesture_evaluation.sh (each is trained here when missing; both resume).
# Two workers run side by side, one CPU thread each: joint then disjoint, and no_audio then no_prior
# (about an hour each).
# Writes experiments/reports/gesture_model/ (gesture_models_test.{json,md}, Table-1 report, PNGs, times).
# Usage: experiments/gesture_model.sh [STEPS] [SPEECH_LOSSES] [JOINT_STEPS]   (defaults: 900 adversarial 1200)
# Ours (joint) and disjoint train JOINT_STEPS (ours ≤ 45 min on one thread); no prior and no audio train STEPS.
set -euo pipefail
cd "$(dirname "$0")/.."
STEPS=${1:-900}
SPEECH_LOSSES=${2:-adversarial}
JOINT_STEPS=${3:-1200}
source experiments/common.sh
REPORT=experiments/reports/gesture_model
SPEECH="$WORK/speech_$SPEECH_LOSSES"
[ -f "$SPEECH/model.json" ] || bash experiments/speech_disentanglement.sh 1300 "$SPEECH_LOSSES"
[ -f "$WORK/extractor/model.json" ] || $EG train extractor --data "$CACHE" --out "$WORK/extractor" --steps 600 \
    --checkpoint-every 100 --quiet
mkdir -p "$REPORT"

train() {  # variant -> trains into $WORK/gesture_<variant> on one thread, writes its wall time
    local variant=$1 start steps=$STEPS
    if [ "$variant" = joint ] || [ "$variant" = disjoint ]; then steps=$JOINT_STEPS; fi
    start=$(date +%s)
    # disjoint: the first half of the steps trains the prior, the second half the denoiser
    OMP_NUM_THREADS=1 $EG train gesture --variant "$variant" --data "$CACHE" --speech "$SPEECH" \
        --out "$WORK/gesture_$variant" --steps "$steps" --checkpoint-every 100 --quiet \
        --set "disjoint_prior_steps=$((steps / 2))"
    echo "$variant: $(( $(date +%s) - start )) s for $steps steps (1 thread, beside another training)" \
        > "$WORK/gesture_$variant.time"
}
queue() { for variant in "$@"; do train "$variant"; done; }  # one worker: its variants in turn
queue joint disjoint & queue no_audio no_prior & wait
cat "$WORK"/gesture_{joint,disjoint,no_prior,no_audio}.time | tee "$REPORT/training_time.txt"

$EG evaluate gesture --data "$CACHE" --extractor "$WORK/extractor" --split test --out "$REPORT" --overwrite \
    --model "ours=$WORK/gesture_joint" --model "disjoint=$WORK/gesture_disjoint" \
    --model "no prior=$WORK/gesture_no_prior" --model "no audio model=$WORK/gesture_no_audio"
