#!/usr/bin/env bash
# Real voices that carry emotions in the speech model's training: the voice packs of the game Hedgewars
# (experiments/game_voices.py: voice actors' lines labelled by what their words say; three packs held out),
# as labelled real speech (`train speech --set real_labelled=MANIFEST`) in the recipe's second speech stage
# (recipe.sh: speech_second_stage, 700 steps from make model's first stage FIRST), calibrated as the recipe
# does. Against the shipped speech model, on val:
#   - word_readers.py: thirteen volunteers reading word lists (KTuberling), never trained or calibrated on, as
#     recorded (neutral is right) and given each emotion;
#   - perception_shift.py: the val speakers' synthetic voices, never trained on, through changed recordings;
#   - game_voices.py hear: the held-out packs, heard as labelled.
# Reports in experiments/reports/game_voices/ (val only). About 40 min on 2 CPU cores; every step resumes.
# Needs Debian's hedgewars-data (`apt-get install hedgewars-data`, 160 MB; not part of `make setup`), and
# ktuberling-data and the recipe's real voices (`make setup`).
# Usage: experiments/game_voices.sh FIRST_SPEECH_STAGE
set -euo pipefail
FIRST=${1:?usage: experiments/game_voices.sh FIRST_SPEECH_STAGE}
cd "$(dirname "$0")/.."
source experiments/common.sh
source experiments/recipe.sh
RUN=$WORK/game_voices
REPORT=experiments/reports/game_voices
SHIPPED=src/emogesture/assets/model/speech.json
mkdir -p "$RUN" "$REPORT"
[ -f "$RUN/labels.csv" ] || .venv/bin/python experiments/game_voices.py "$RUN/labels.csv"
speech_second_stage "$RUN/speech" "$FIRST" "$CACHE" "$RUN/times.txt" --set "real_labelled=$RUN/labels.csv"
speech_calibrated speech_calibrated "$RUN/speech" "${PERCEPTION[@]}"
[ -f "$REPORT/game_voices/game_voices.json" ] || .venv/bin/python experiments/game_voices.py hear \
    "$RUN/labels.csv" "$REPORT/game_voices" shipped="$SHIPPED" stage="$RUN/speech_calibrated"
[ -f "$REPORT/word_readers/word_readers.json" ] || .venv/bin/python experiments/word_readers.py \
    "$REPORT/word_readers" shipped="$SHIPPED" stage="$RUN/speech_calibrated"
perception_val speech_calibrated
cp "$RUN/times.txt" "$REPORT/training_time.txt"
