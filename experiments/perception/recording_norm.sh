#!/usr/bin/env bash
# Emotion read against the recording itself: two speech models trained like the bundle's recipe at 600
# steps (--losses adversarial, wave_augment 0.5) on the experiments' corpus prepared with
# `--set recording_norm=level` and `=spectrum`, calibrated on val, scored on the val split's held-out
# voices under changed recording conditions (perception_shift.py) and on real read speech at three gains
# (real_perception.py), beside the same recipe without it (`none`: the corpus's own cache).
# About 70 min on 2 CPU cores (the trainings side by side, one thread each).
# Usage: experiments/perception/recording_norm.sh
set -euo pipefail
cd "$(dirname "$0")/../.."
source experiments/common.sh
RUN=$WORK/recording_norm
REPORT=experiments/perception/reports/recording_norm
mkdir -p "$RUN" "$REPORT"
modes=(none level spectrum)
ln -sfn "$(realpath "$CACHE")" "$RUN/cache_none"
for m in level spectrum; do
    $EG prepare "$CORPUS" --out "$RUN/cache_$m" --set split_source=csv+actor --set recording_norm=$m --quiet &
done
wait
for m in "${modes[@]}"; do
    grep -qs '"step": 600' "$RUN/speech_$m/model.json" || OMP_NUM_THREADS=1 $EG train speech --data "$RUN/cache_$m" \
        --out "$RUN/speech_$m" --losses adversarial --steps 600 --checkpoint-every 100 --set wave_augment=0.5 --quiet &
done
wait
models=()
for m in "${modes[@]}"; do
    [ -f "$RUN/speech_${m}_cal/model.json" ] || $EG calibrate speech --model "$RUN/speech_$m" --data "$RUN/cache_$m" \
        --out "$RUN/speech_${m}_cal"
    [ -f "$RUN/shift_$m/perception_shift.json" ] || .venv/bin/python experiments/perception_shift.py "$RUN/speech_${m}_cal" "$RUN/cache_$m" "$RUN/shift_$m" val
    cp "$RUN/shift_$m/perception_shift.md" "$REPORT/val_$m.md"
    cp "$RUN/shift_$m/perception_shift.json" "$REPORT/val_$m.json"
    models+=("$m=$RUN/speech_${m}_cal")
done
.venv/bin/python experiments/real_perception.py "$REPORT" "${models[@]}"
