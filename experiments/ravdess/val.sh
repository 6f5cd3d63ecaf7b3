#!/usr/bin/env bash
# The speech model trained on with RAVDESS's train actors, scored on its val actors (experiments/ravdess/README.md).
# The bundled speech model trained on for 700 steps with the recipe's second-stage settings and one window of
# the train actors in each quadruple (ravdess_stage, calm left out), calibrated as the recipe does without
# labelled speech (real voices' and telephone-band means) and with it (--labelled); each scored on the val
# actors (calm heard as neutral) with three hearings and with one. Usage: RAVDESS=.../audio_speech_actors_01-24 experiments/ravdess/val.sh
set -euo pipefail
cd "$(dirname "$0")/../.."
source experiments/common.sh
source experiments/recipe.sh
RUN=$WORK/ravdess
REPORT=experiments/ravdess/reports
mkdir -p "$RUN" "$REPORT"
ravdess_manifest "$RUN/ravdess.csv"
[ -f "$RUN/ravdess_calm.csv" ] || $EG labelled-speech ravdess "$RAVDESS" --out "$RUN/ravdess_calm.csv" "${RAVDESS_SPLIT[@]}" --calm neutral
ravdess_stage "$RUN/nocalm" src/emogesture/assets/model/speech.json "$CACHE" "$RUN/ravdess.csv" "$RUN/times.txt"
[ -f "$RUN/nocalm/cal/model.json" ] || $EG calibrate speech --model "$RUN/nocalm" --data "$CACHE" --out "$RUN/nocalm/cal" "${PERCEPTION[@]}"
[ -f "$RUN/nocalm/cal_labelled/model.json" ] || $EG calibrate speech --model "$RUN/nocalm" --data "$CACHE" \
    --out "$RUN/nocalm/cal_labelled" --labelled "$RUN/ravdess.csv" --telephone-means
for model in shipped=src/emogesture/assets/model/speech.json nocalm="$RUN/nocalm/cal" nocalm_labelled="$RUN/nocalm/cal_labelled"; do
    for semitones in 3 0; do
        .venv/bin/python experiments/ravdess/perception_val.py "${model#*=}" "$RUN/ravdess_calm.csv" val \
            "$REPORT/${model%%=*}.val.s$semitones.json" "$semitones"
    done
done
cp "$RUN/times.txt" "$REPORT/training_time.txt"
