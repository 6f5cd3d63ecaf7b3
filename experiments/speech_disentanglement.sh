#!/usr/bin/env bash
# Issue 3 experiment: the tiny speech disentangler on the default synthetic corpus (CPU, <= 30 min of
# training), evaluated on held-out texts. Writes experiments/reports/speech_tiny.{json,md} and PNGs.
# Usage: experiments/speech_disentanglement.sh [STEPS] [LOSSES]   (defaults: 900 full)
set -euo pipefail
cd "$(dirname "$0")/.."
STEPS=${1:-900}
LOSSES=${2:-full}
EG=.venv/bin/emogesture
WORK=outputs/experiments
$EG corpus --out outputs/demo/corpus --resume --quiet
$EG prepare outputs/demo/corpus --out outputs/demo/cache --quiet
start=$(date +%s)
$EG train speech --data outputs/demo/cache --out "$WORK/speech_$LOSSES" --losses "$LOSSES" --steps "$STEPS" \
    --checkpoint-every 100 --quiet
echo "training wall time: $(( $(date +%s) - start )) s" | tee "$WORK/speech_$LOSSES.time"
$EG evaluate speech "$WORK/speech_$LOSSES" --data outputs/demo/cache --split test \
    --out experiments/reports/speech_tiny_$LOSSES --overwrite
