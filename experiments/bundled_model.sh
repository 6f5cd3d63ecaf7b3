#!/usr/bin/env bash
# Rebuilds the model bundled with the package (src/emogesture/assets/model/) from scratch, with the
# project's own recipe, on the experiments' synthetic corpus (common.sh: 30 voices, split by text and by
# speaker); `make model` runs it. Every step resumes when re-run (finished trainings are not redone).
# About 110 min on 2 CPU cores (the second speech stage measured whole with its data workers, the first
# on an 80-step run; the bundled model's own build, before them, took about 135 min, its trainings in
# reports/bundled_model/training_time.txt).
#   1. the speech model (tiny, --losses adversarial, 1300 steps, half its windows heard through augmented
#      recording conditions) on the train texts of the train speakers only, so that the val texts and
#      voices stay unseen for the calibrations below and the test texts and voices for the model card;
#      then trained on from there for 700 steps (lr 5e-4) with three quarters of its windows augmented,
#      voices moved by up to 6 semitones and more level changes (`speech_tuned`, the one used below);
#   2. the evaluation suite's motion feature extractor M (600 steps), beside the first stage;
#   3. the gesture model (tiny, joint, 2400 steps; its residual noise is calibrated on val);
#   4. the speech model's emotion perception (class means on train, trust threshold on val), and the
#      gesture model's fallback style for unfamiliar voices (the training speaker whose style gives its
#      typical motion on the val split's neutral windows);
#   5. the bundle: weights in float16, config and statistics in JSON, SHA256SUMS; the gesture model with
#      the tiny preset's generation settings ($GENERATION in common.sh; chosen on val for this recipe:
#      reports/bundled_model/generation_sweep_val.md), however old its run;
#   6. the bundle scored on the test split (speech and gesture reports, --emotion auto vs own, real
#      recorded speech against the test takes of the same emotion: `evaluate real`), and
#      the model card written from those numbers; then the bundle is copied into the package.
# Usage: experiments/bundled_model.sh
set -euo pipefail
cd "$(dirname "$0")/.."
source experiments/common.sh
RUN=$WORK/bundled
REPORT=experiments/reports/bundled_model
mkdir -p "$RUN" "$REPORT"

timed() {  # name command... : runs a training step and appends its wall time to $RUN/times.txt
    local name=$1 start
    shift
    start=$(date +%s)
    "$@"
    echo "$name: $(( $(date +%s) - start )) s" >> "$RUN/times.txt"
}
# the speech model and the extractor side by side, one thread each (two for one left alone); the speech
# model's windows are augmented in 2 data workers beside its one training thread (the same draws)
todo=()
grep -qs '"step": 1300' "$RUN/speech/model.json" || todo+=(speech)
grep -qs '"step": 600' "$RUN/extractor/model.json" || todo+=(extractor)
threads=$(( ${#todo[@]} > 1 ? 1 : 2 ))
pids=()
for model in "${todo[@]}"; do
    if [ "$model" = speech ]; then
        timed speech $EG train speech --data "$CACHE" --out "$RUN/speech" --losses adversarial --steps 1300 \
            --checkpoint-every 100 --set wave_augment=0.5 --set num_workers=2 --quiet &
    else
        OMP_NUM_THREADS=$threads timed extractor $EG train extractor --data "$CACHE" --out "$RUN/extractor" \
            --steps 600 --checkpoint-every 100 --quiet &
    fi
    pids+=($!)
done
for pid in "${pids[@]}"; do wait "$pid"; done
SPEECH=$RUN/speech_tuned
grep -qs '"step": 700' "$SPEECH/model.json" || timed speech_tuned $EG train speech --data "$CACHE" \
    --init-from "$RUN/speech" --out "$SPEECH" --losses adversarial --steps 700 --checkpoint-every 100 \
    --set wave_augment=0.75 --set wave.voice=0.6 --set wave.voice_semitones=6 --set wave.loudness=0.6 \
    --set lr=5e-4 --set lr_decay_start=100 --set num_workers=2 --quiet
grep -qs '"step": 2400' "$RUN/gesture/model.json" || timed gesture $EG train gesture --data "$CACHE" --speech "$SPEECH" \
    --out "$RUN/gesture" --steps 2400 --checkpoint-every 200 --quiet

# 4. emotion perception (train means, val threshold) on a copy of the speech model, the fallback style (val)
# on a copy of the gesture model; 5. the bundle
[ -f "$RUN/speech_calibrated/model.json" ] || $EG calibrate speech --model "$SPEECH" --data "$CACHE" \
    --out "$RUN/speech_calibrated"
[ -f "$RUN/gesture_styled/model.json" ] || $EG calibrate style --model "$RUN/gesture" --data "$CACHE" \
    --out "$RUN/gesture_styled"
BUNDLE=$RUN/bundle
$EG bundle --speech "$RUN/speech_calibrated" --gesture "$RUN/gesture_styled" --extractor "$RUN/extractor" --out "$BUNDLE" \
    --overwrite "${GENERATION[@]}"

# 6. the bundle, as shipped (float16), scored once on the test texts; the card; into the package
$EG evaluate speech "$BUNDLE/speech.json" --data "$CACHE" --split test --out "$REPORT/speech" --overwrite
$EG evaluate gesture --data "$CACHE" --extractor "$BUNDLE/extractor.json" --split test --out "$REPORT/gesture" \
    --overwrite --model "ours=$BUNDLE/gesture.json"
.venv/bin/python experiments/perception_shift.py "$BUNDLE/speech.json" "$CACHE" "$REPORT"
$EG evaluate real --data "$CACHE" --model "$BUNDLE/gesture.json" --out "$REPORT/real" --overwrite
cp "$RUN/times.txt" "$REPORT/training_time.txt"
.venv/bin/python experiments/model_card.py "$BUNDLE" "$REPORT" "$RUN/times.txt" "$CACHE"
ASSETS=src/emogesture/assets/model
mkdir -p "$ASSETS"
rm -f "$ASSETS"/*
cp "$BUNDLE"/{speech,gesture,extractor}.{json,safetensors} "$BUNDLE"/{MODEL_CARD.md,card.json,SHA256SUMS} "$ASSETS/"
$EG model-info
