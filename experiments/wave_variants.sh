#!/usr/bin/env bash
# The speech model of the recipe with its augmented windows made once, before training (`--set wave_variants=8`:
# eight draws of the recording conditions per training window, kept in memory), instead of afresh in the data
# workers at every step: both stages of recipe.sh's speech training (1300 steps with half of the windows
# augmented, then 700 with the harder second-stage conditions), one process with both cores, each stage timed;
# calibrated as the recipe does (studio voices' means). Beside BASE (the bundled speech model, trained with the
# augmentation drawn afresh; calibrated the same way), on val:
#   - perception_shift.py (the val speakers' voices, never trained on, through changed recordings; BASE's is
#     real_voice_means.sh's base_means);
#   - real_perception.py and real_voice_emotions.py: the real recordings (never trained on: other people).
# Reports in experiments/reports/wave_variants/ (val only). About 50 min on 2 CPU cores; every step resumes.
# Usage: experiments/wave_variants.sh BASE_SPEECH_MODEL
set -euo pipefail
BASE=${1:?usage: experiments/wave_variants.sh BASE_SPEECH_MODEL}
cd "$(dirname "$0")/.."
source experiments/common.sh
source experiments/recipe.sh
RUN=$WORK/wave_variants
REPORT=experiments/reports/wave_variants
VARIANTS=(--set wave_variants=8)
mkdir -p "$RUN" "$REPORT"
grep -qs '"step": 1300' "$RUN/speech/model.json" || timed "$RUN/times.txt" speech $EG train speech --data "$CACHE" \
    --out "$RUN/speech" --losses adversarial --steps 1300 --checkpoint-every 100 --set wave_augment=0.5 \
    "${VARIANTS[@]}" --quiet
grep -qs '"step": 700' "$RUN/speech_tuned/model.json" || timed "$RUN/times.txt" speech_tuned $EG train speech \
    --data "$CACHE" --init-from "$RUN/speech" --out "$RUN/speech_tuned" --losses adversarial --steps 700 \
    --checkpoint-every 100 "${SPEECH_HARD[@]}" "${VARIANTS[@]}" --quiet
speech_calibrated base_means "$BASE" --real-voices "$REAL_VOICES"
speech_calibrated variants_means "$RUN/speech_tuned" --real-voices "$REAL_VOICES"
# (BASE's own: reports/real_voice_means/perception_base_means, the same model and calibration)
[ -f "$REPORT/perception_variants_means/perception_shift.md" ] || .venv/bin/python experiments/perception_shift.py \
    "$RUN/variants_means" "$CACHE" "$REPORT/perception_variants_means" val
MODELS=(base_means="$RUN/base_means" variants_means="$RUN/variants_means")
.venv/bin/python experiments/real_perception.py "$REPORT/real" "${MODELS[@]}"
.venv/bin/python experiments/real_voice_emotions.py "$REPORT/real_voice_emotions" "${MODELS[@]}"
cp "$RUN/times.txt" "$REPORT/training_time.txt"
