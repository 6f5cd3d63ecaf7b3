#!/usr/bin/env bash
# Issue 3 experiment: the tiny speech disentangler on the default synthetic corpus (CPU, <= 30 min of
# training on the train and val texts), evaluated on the held-out test texts. Writes experiments/reports/speech_tiny_<LOSSES>/ (JSON, markdown,
# PNGs, training time). LOSSES: full (the paper's seven terms), adversarial (plus latent adversaries),
# emotion_only, style_only.
# Usage: experiments/speech_disentanglement.sh [STEPS] [LOSSES]   (defaults: 1300 adversarial)
set -euo pipefail
cd "$(dirname "$0")/.."
STEPS=${1:-1300}
LOSSES=${2:-adversarial}
source experiments/common.sh
start=$(date +%s)
$EG train speech --data "$CACHE" --out "$WORK/speech_$LOSSES" --losses "$LOSSES" --steps "$STEPS" \
    --set "train_splits=[train, val]" --checkpoint-every 100 --quiet
elapsed=$(( $(date +%s) - start ))
$EG evaluate speech "$WORK/speech_$LOSSES" --data "$CACHE" --split test \
    --out experiments/reports/speech_tiny_$LOSSES --overwrite
echo "training wall time: $elapsed s for $STEPS steps ($(nproc) cores)" | tee experiments/reports/speech_tiny_$LOSSES/training_time.txt
