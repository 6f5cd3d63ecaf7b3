#!/usr/bin/env bash
# Speech disentanglement experiment: the tiny speech disentangler on the default synthetic corpus (CPU, <= 30 min of
# training on the train texts), evaluated on the val texts to compare settings, and on the test texts
# once for the setting that is reported. Writes experiments/speech_model/reports/speech_tiny_<NAME>/speech_<SPLIT>.*
# (JSON, markdown with checks, PNGs) and the training time.
# LOSSES: full (the paper's seven terms), adversarial (plus latent adversaries), emotion_only, style_only;
# NAME is LOSSES. (A word-order scramble of the emotion encoder's input, once a third argument, was tried and
# not adopted: reports/speech_tiny_adversarial_scramble32/.)
# Usage: experiments/speech_model/speech_disentanglement.sh [STEPS] [LOSSES] [SPLIT]
#   (defaults: 1300 adversarial val; SPLIT=test once the setting is chosen)
set -euo pipefail
cd "$(dirname "$0")/../.."
STEPS=${1:-1300}
LOSSES=${2:-adversarial}
SPLIT=${3:-val}
NAME=$LOSSES
source experiments/common.sh
REPORT=experiments/speech_model/reports/speech_tiny_$NAME
mkdir -p "$REPORT"
if ! grep -qs "\"step\": $STEPS" "$WORK/speech_$NAME/model.json"; then
    start=$(date +%s)
    $EG train speech --data "$CACHE" --out "$WORK/speech_$NAME" --losses "$LOSSES" --steps "$STEPS" \
        --set "train_splits=[train]" --checkpoint-every 100 --quiet
    echo "training wall time: $(( $(date +%s) - start )) s for $STEPS steps ($(nproc) cores), train texts only" \
        | tee "$REPORT/training_time.txt"
fi
$EG evaluate speech "$WORK/speech_$NAME" --data "$CACHE" --split "$SPLIT" --out "$REPORT" --overwrite
