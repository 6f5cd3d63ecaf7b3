#!/usr/bin/env bash
# Real voices read without acted emotion, taught as neutral: a trained speech model (BASE; for the report, the
# bundled one, the recipe's second stage) trained on for 500 steps with that stage's settings (recipe.sh), once with `--set real_neutral=[...]` (a window
# of the Asterisk prompts in French, Italian and Russian, three professional voices, per quadruple, its
# emotion classifier taught neutral) and once without (the control: the same extra steps), then once with
# the real windows' emotion latents also pulled toward the batch's neutral ones (`real_neutral_pull`), each
# calibrated on val; then, beside BASE:
#   - perception_shift.py on val (the val speakers' voices, never trained on, through changed recordings);
#   - real_perception.py: the real recordings (never trained on: other speakers, one of them another genre)
#     at three gains;
#   - real_voice_emotions.py: the same recordings given each emotion's corpus prosody, to see that the
#     model still hears the corpus's emotions in a real voice (not "every real voice is neutral").
# Reports in experiments/reports/real_neutral/ (val only). About 75 min on 2 CPU cores; every step resumes.
# Needs Debian's asterisk-core-sounds-{fr,it,ru}-g722 (`make setup` installs them).
# Usage: experiments/real_neutral.sh BASE_SPEECH_MODEL
set -euo pipefail
BASE=${1:?usage: experiments/real_neutral.sh BASE_SPEECH_MODEL}
cd "$(dirname "$0")/.."
source experiments/common.sh
source experiments/recipe.sh
RUN=$WORK/real_neutral
REPORT=experiments/reports/real_neutral
mkdir -p "$RUN" "$REPORT"
# 500 steps more from BASE with the recipe's second-stage settings, with and without the real voices, side by side
STAGE=(--data "$CACHE" --init-from "$BASE" --losses adversarial --steps 500 --checkpoint-every 100 "${SPEECH_HARD[@]}"
       --set num_workers=1 --quiet)
speech_more anchored 1 --set "real_neutral=[$REAL_VOICES]" &
speech_more control 1 &
wait
# the same with the real windows' emotion latents also pulled toward the batch's neutral latents, alone
speech_more anchored_pull 2 --set "real_neutral=[$REAL_VOICES]" --set real_neutral_pull=1 --set num_workers=2
for name in anchored control anchored_pull; do
    speech_calibrated "${name}_calibrated" "$RUN/$name"
    .venv/bin/python experiments/perception_shift.py "$RUN/${name}_calibrated" "$CACHE" "$REPORT/perception_$name" val
done
.venv/bin/python experiments/perception_shift.py "$BASE" "$CACHE" "$REPORT/perception_base" val
MODELS=(base="$BASE" control="$RUN/control_calibrated" anchored="$RUN/anchored_calibrated"
        anchored_pull="$RUN/anchored_pull_calibrated")
real_reports "${MODELS[@]}"
