#!/usr/bin/env bash
# Speakers whose own speaking style varies as widely as real people's: the bundled model's recipe
# (recipe.sh) on the experiments' corpus rebuilt with `corpus --speaker-prosody-scale 2.5` (the speakers'
# own pitch range, rate, loudness and tilt 2.5 times as far from the middle, the voices' pitch kept), then
# compared with the shipped model on val (the val speakers' voices, never trained on):
#   - evaluate real: the real recordings against each corpus's val takes of the same emotion;
#   - the emotion perception under changed recordings (perception_shift.py) on the shipped corpus's val
#     voices, for both speech models;
#   - evaluate gesture on the wider corpus's val texts (its own extractor): the candidate, the shipped
#     model, and a gesture model trained on the wider corpus with the shipped speech model (which of the
#     two, the corpus or the speech model, moves the motion); and, as a control, the same gesture training
#     on the shipped corpus with the shipped speech model, on the shipped corpus's val texts.
# Reports in experiments/reports/speaker_spread/ (val only: the candidate was not adopted, so test was
# never scored). About 2 h on 2 CPU cores when nothing is trained yet; every step resumes.
# Usage: experiments/speaker_spread.sh
set -euo pipefail
cd "$(dirname "$0")/.."
source experiments/common.sh
source experiments/recipe.sh
RUN=$WORK/speaker_spread
REPORT=experiments/reports/speaker_spread
SHIPPED=src/emogesture/assets/model
mkdir -p "$REPORT"
wide_speakers_cache
train_bundle "$RUN" "$WIDE_CACHE"
train_gesture "$RUN/gesture_shipped_speech" "$WIDE_CACHE" "$SHIPPED/speech.json" "$RUN/times.txt" gesture_shipped_speech
# the control: the same gesture training on the shipped corpus with the shipped speech model
train_gesture "$RUN/gesture_control" "$CACHE" "$SHIPPED/speech.json" "$RUN/times.txt" gesture_control
cp "$RUN/times.txt" "$REPORT/training_time.txt"

$EG evaluate real --data "$WIDE_CACHE" --split val --model "$RUN/bundle/gesture.json" --out "$REPORT/real_candidate" \
    --overwrite
$EG evaluate real --data "$CACHE" --split val --model "$SHIPPED/gesture.json" --out "$REPORT/real_shipped" --overwrite
.venv/bin/python experiments/perception_shift.py "$RUN/bundle/speech.json" "$CACHE" "$REPORT/perception_candidate" val
.venv/bin/python experiments/perception_shift.py "$SHIPPED/speech.json" "$CACHE" "$REPORT/perception_shipped" val
$EG evaluate gesture --data "$WIDE_CACHE" --extractor "$RUN/extractor" --split val --out "$REPORT/gesture" \
    --overwrite --long-audio 0 --model "candidate=$RUN/bundle/gesture.json" --model "shipped=$SHIPPED/gesture.json" \
    --model "wide_corpus_shipped_speech=$RUN/gesture_shipped_speech"
$EG evaluate gesture --data "$CACHE" --extractor "$SHIPPED/extractor.json" --split val --out "$REPORT/gesture_control" \
    --overwrite --long-audio 0 --model "control=$RUN/gesture_control" --model "shipped=$SHIPPED/gesture.json"
rm -f "$REPORT"/gesture*/*.png  # the confusion plots stay out of the repository; the tables hold the numbers
