#!/usr/bin/env bash
# Issue 3 experiment: the tiny speech disentangler on the default synthetic corpus (CPU, <= 30 min of
# training on the train and val texts), evaluated on the held-out test texts. Writes
# experiments/reports/speech_tiny_<NAME>/ (JSON, markdown, PNGs, training time).
# LOSSES: full (the paper's seven terms), adversarial (plus latent adversaries), emotion_only, style_only.
# SCRAMBLE: segment length (fbank frames) of the word-order scramble the emotion encoder sees in
# training (0 = off); NAME is LOSSES, plus _scramble<SCRAMBLE> when it is on.
# Usage: experiments/speech_disentanglement.sh [STEPS] [LOSSES] [SCRAMBLE]   (defaults: 1300 adversarial 0)
set -euo pipefail
cd "$(dirname "$0")/.."
STEPS=${1:-1300}
LOSSES=${2:-adversarial}
SCRAMBLE=${3:-0}
NAME=$LOSSES
[ "$SCRAMBLE" = 0 ] || NAME="${LOSSES}_scramble$SCRAMBLE"
source experiments/common.sh
start=$(date +%s)
$EG train speech --data "$CACHE" --out "$WORK/speech_$NAME" --losses "$LOSSES" --steps "$STEPS" \
    --set "train_splits=[train, val]" --set "emotion_scramble=$SCRAMBLE" --checkpoint-every 100 --quiet
elapsed=$(( $(date +%s) - start ))
$EG evaluate speech "$WORK/speech_$NAME" --data "$CACHE" --split test \
    --out "experiments/reports/speech_tiny_$NAME" --overwrite
echo "training wall time: $elapsed s for $STEPS steps ($(nproc) cores)" | tee "experiments/reports/speech_tiny_$NAME/training_time.txt"
