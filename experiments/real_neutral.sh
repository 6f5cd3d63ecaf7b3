#!/usr/bin/env bash
# Real voices read without acted emotion, taught as neutral: the bundled speech model trained on for 500
# steps with the recipe's second-stage settings (recipe.sh), once with `--set real_neutral=[...]` (a window
# of the Asterisk prompts in French, Italian and Russian, three professional voices, per quadruple, its
# emotion classifier taught neutral) and once without (the control: the same extra steps), both calibrated
# on val; then, beside the shipped speech model:
#   - perception_shift.py on val (the val speakers' voices, never trained on, through changed recordings);
#   - real_perception.py: the real recordings (never trained on: other speakers, one of them another genre)
#     at three gains;
#   - real_voice_emotions.py: the same recordings given each emotion's corpus prosody, to see that the
#     model still hears the corpus's emotions in a real voice (not "every real voice is neutral").
# Reports in experiments/reports/real_neutral/ (val only). About 40 min on 2 CPU cores; every step resumes.
# Needs Debian's asterisk-core-sounds-{fr,it,ru}-g722 (`make setup` installs them).
# Usage: experiments/real_neutral.sh
set -euo pipefail
cd "$(dirname "$0")/.."
source experiments/common.sh
RUN=$WORK/real_neutral
REPORT=experiments/reports/real_neutral
SHIPPED=src/emogesture/assets/model
mkdir -p "$RUN" "$REPORT"
# the recipe's second stage (recipe.sh), 500 steps from the shipped model; the two runs side by side
STAGE=(--data "$CACHE" --init-from "$SHIPPED/speech.json" --losses adversarial --steps 500 --checkpoint-every 100
       --set wave_augment=0.75 --set wave.voice=0.6 --set wave.voice_semitones=6 --set wave.loudness=0.6
       --set lr=5e-4 --set lr_decay_start=100 --set num_workers=1 --quiet)
train_one() {  # NAME [--set ...]
    local name=$1 start
    shift
    grep -qs '"step": 500' "$RUN/$name/model.json" && return
    start=$(date +%s)
    OMP_NUM_THREADS=1 $EG train speech --out "$RUN/$name" "${STAGE[@]}" "$@"
    echo "$name: $(( $(date +%s) - start )) s (one thread, beside the other run)" >> "$RUN/times.txt"
}
train_one anchored --set "real_neutral=[fr_june, it_carlo, ru_ivr]" &
train_one control &
wait
for name in anchored control; do
    [ -f "$RUN/${name}_calibrated/model.json" ] || $EG calibrate speech --model "$RUN/$name" --data "$CACHE" \
        --out "$RUN/${name}_calibrated"
    .venv/bin/python experiments/perception_shift.py "$RUN/${name}_calibrated" "$CACHE" "$REPORT/perception_$name" val
done
.venv/bin/python experiments/perception_shift.py "$SHIPPED/speech.json" "$CACHE" "$REPORT/perception_shipped" val
MODELS=(shipped="$SHIPPED/speech.json" control="$RUN/control_calibrated" anchored="$RUN/anchored_calibrated")
.venv/bin/python experiments/real_perception.py "$REPORT/real" "${MODELS[@]}"
.venv/bin/python experiments/real_voice_emotions.py "$REPORT/real_voice_emotions" "${MODELS[@]}"
cp "$RUN/times.txt" "$REPORT/training_time.txt"
