#!/usr/bin/env bash
# The speech model learnt from speakers whose own speaking style varies as widely as real people's, the
# gesture side left as shipped: both speech stages of the recipe (recipe.sh) on the experiments' corpus rebuilt
# with `corpus --speaker-prosody-scale 2.5` (the speakers' own pitch range, rate, loudness and tilt 2.5 times as
# far from the middle, the voices' pitch kept), its perception calibrated as the recipe does on the shipped
# corpus (class means on its train takes, the trust threshold on its val voices), so that the gesture model
# would go on learning from the shipped corpus, whose timing it follows. Compared with the shipped speech model
# on val only:
#   - perception_shift.py on the shipped corpus's val speakers' voices (never trained on) through changed
#     recordings;
#   - word_readers.py: the validation set of real voices (never trained or calibrated on).
# Reports in experiments/reports/wide_speakers/. About 50 min on 2 CPU cores; every step resumes.
# Usage: experiments/wide_speakers.sh
set -euo pipefail
cd "$(dirname "$0")/.."
source experiments/common.sh
source experiments/recipe.sh
RUN=$WORK/wide_speakers
REPORT=experiments/reports/wide_speakers
SHIPPED=src/emogesture/assets/model
mkdir -p "$RUN" "$REPORT"
wide_speakers_cache
grep -qs '"step": 1300' "$RUN/speech/model.json" || timed "$RUN/times.txt" speech $EG train speech \
    --data "$WIDE_CACHE" --out "$RUN/speech" --losses adversarial --steps 1300 --checkpoint-every 100 \
    --set wave_augment=0.5 "${SPEECH_VARIANTS[@]}" --quiet
speech_second_stage "$RUN/speech_tuned" "$RUN/speech" "$WIDE_CACHE" "$RUN/times.txt"
speech_calibrated candidate "$RUN/speech_tuned" "${PERCEPTION[@]}"
perception_val candidate
[ -f "$REPORT/word_readers/word_readers.md" ] || .venv/bin/python experiments/word_readers.py \
    "$REPORT/word_readers" shipped="$SHIPPED/speech.json" candidate="$RUN/candidate"
cp "$RUN/times.txt" "$REPORT/training_time.txt"
