#!/usr/bin/env bash
# Real voices given the corpus's emotions: a trained speech model (BASE; for the report, the bundled one, the
# recipe's second stage) trained on for 500 steps with that stage's settings (recipe.sh), each quadruple
# bringing a window of the Asterisk prompts in French, Italian and Russian (three professional voices) that
# is given a random emotion's speech prosody as the corpus gives it (`real_emotion_share=0.875`: the eight
# emotions alike) and taught as that emotion; once with the classifier's loss alone, once with the real
# windows' emotion latents also pulled toward the batch's corpus latents of their emotion. Each calibrated
# on val; then, beside BASE and real_neutral.sh's control (the same extra steps without real voices):
#   - perception_shift.py on val (the val speakers' voices, never trained on, through changed recordings);
#   - real_perception.py: the real recordings (never trained on) at three gains;
#   - real_voice_emotions.py: the same recordings given each emotion's corpus prosody (the cues these
#     models were taught on other voices: it asks whether they carry over to voices never heard).
# Reports in experiments/reports/real_emotions/ (val only). About 75 min on 2 CPU cores; every step resumes.
# Needs Debian's asterisk-core-sounds-{fr,it,ru}-g722 (`make setup` installs them) and real_neutral.sh's
# control run.
# Usage: experiments/real_emotions.sh BASE_SPEECH_MODEL
set -euo pipefail
BASE=${1:?usage: experiments/real_emotions.sh BASE_SPEECH_MODEL}
cd "$(dirname "$0")/.."
source experiments/common.sh
source experiments/recipe.sh
RUN=$WORK/real_emotions
CONTROL=$WORK/real_neutral/control_calibrated
REPORT=experiments/reports/real_emotions
mkdir -p "$RUN" "$REPORT"
[ -f "$CONTROL/model.json" ] || { echo "run experiments/real_neutral.sh first (its control)" >&2; exit 1; }
STAGE=(--data "$CACHE" --init-from "$BASE" --losses adversarial --steps 500 --checkpoint-every 100 "${SPEECH_HARD[@]}"
       --set num_workers=1 --quiet --set "real_neutral=[$REAL_VOICES]" --set real_emotion_share=0.875)
speech_more emotions 1 &
speech_more emotions_pull 1 --set real_neutral_pull=0.3 &
wait
for name in emotions emotions_pull; do
    speech_calibrated "${name}_calibrated" "$RUN/$name"
    .venv/bin/python experiments/perception_shift.py "$RUN/${name}_calibrated" "$CACHE" "$REPORT/perception_$name" val
done
MODELS=(base="$BASE" control="$CONTROL" emotions="$RUN/emotions_calibrated"
        emotions_pull="$RUN/emotions_pull_calibrated")
real_reports "${MODELS[@]}"
