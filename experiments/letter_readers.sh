#!/usr/bin/env bash
# Ten volunteers reading letters aloud (KLettres, emogesture.data.real_speech.LETTER_READERS) beside the three
# studio voices, two ways, each against the shipped speech model:
#   - means: the shipped speech model calibrated as the recipe does, with all thirteen real voices' means
#     (`calibrate speech --real-voices`; nothing retrained);
#   - stage: the recipe's second speech stage (recipe.sh: speech_second_stage, 700 steps from make model's
#     first stage FIRST) trained again with each quadruple bringing a window of one of the thirteen voices
#     (real_emotions.sh's setting: `real_emotion_share=0.875`, the eight emotions alike, each given as the
#     corpus gives it and taught as that emotion), calibrated with the same voices' means.
# Then, on val:
#   - word_readers.py: thirteen other volunteers reading word lists (KTuberling), never trained or calibrated
#     on, the validation set of real voices: as recorded (neutral is right) and given each emotion;
#   - perception_shift.py for the stage (the val speakers' voices, never trained on, through changed
#     recordings);
#   - real_perception.py: the real-speech check recordings (a check, not a criterion).
# Reports in experiments/reports/letter_readers/ (val only). About 60 min on 2 CPU cores; every step resumes.
# Needs Debian's asterisk-core-sounds-{fr,it,ru}-g722, klettres-data and ktuberling-data (`make setup`).
# Usage: experiments/letter_readers.sh FIRST_SPEECH_STAGE
set -euo pipefail
FIRST=${1:?usage: experiments/letter_readers.sh FIRST_SPEECH_STAGE}
cd "$(dirname "$0")/.."
source experiments/common.sh
source experiments/recipe.sh
RUN=$WORK/letter_readers
REPORT=experiments/reports/letter_readers
SHIPPED=src/emogesture/assets/model/speech.json
LETTERS="letters_ar, letters_cs, letters_es, letters_he, letters_hu, letters_it, letters_ml, letters_nl, letters_pt_br, letters_tn"
VOICES="$REAL_VOICES, $LETTERS"
mkdir -p "$RUN" "$REPORT"
speech_calibrated means "$SHIPPED" --real-voices "$VOICES" --telephone-means
speech_second_stage "$RUN/speech" "$FIRST" "$CACHE" "$RUN/times.txt" \
    --set "real_neutral=[$VOICES]" --set real_emotion_share=0.875
speech_calibrated speech_calibrated "$RUN/speech" --real-voices "$VOICES" --telephone-means
[ -f "$REPORT/word_readers/word_readers.json" ] || .venv/bin/python experiments/word_readers.py \
    "$REPORT/word_readers" shipped="$SHIPPED" means="$RUN/means" stage="$RUN/speech_calibrated"
[ -f "$REPORT/perception_val/perception_shift.json" ] || .venv/bin/python experiments/perception_shift.py \
    "$RUN/speech_calibrated" "$CACHE" "$REPORT/perception_val" val
[ -f "$REPORT/real/real_perception.json" ] || .venv/bin/python experiments/real_perception.py "$REPORT/real" \
    shipped="$SHIPPED" stage="$RUN/speech_calibrated"
