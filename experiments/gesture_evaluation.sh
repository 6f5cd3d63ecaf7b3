#!/usr/bin/env bash
# Issue 4 experiment: train the motion feature extractor M (tiny) on the default synthetic corpus and
# score the ground truth and the built-in baselines on held-out texts (paper Table 1 layout).
# Writes experiments/reports/gesture_eval/gesture_test.{json,md} and confusion PNGs.
# Usage: experiments/gesture_evaluation.sh [STEPS]   (default 600)
set -euo pipefail
cd "$(dirname "$0")/.."
STEPS=${1:-600}
EG=.venv/bin/emogesture
WORK=outputs/experiments
$EG corpus --out outputs/demo/corpus --resume --quiet
$EG prepare outputs/demo/corpus --out outputs/demo/cache --quiet
start=$(date +%s)
$EG train extractor --data outputs/demo/cache --out "$WORK/extractor" --steps "$STEPS" --checkpoint-every 100 --quiet
echo "extractor training wall time: $(( $(date +%s) - start )) s" | tee "$WORK/extractor.time"
$EG evaluate gesture --data outputs/demo/cache --extractor "$WORK/extractor" --split test \
    --out experiments/reports/gesture_eval --overwrite
