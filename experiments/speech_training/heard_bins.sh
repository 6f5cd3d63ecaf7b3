#!/usr/bin/env bash
# How the recipe's second speech stage came to hear the spectrum up to 4 kHz only (recipe.sh's SPEECH_BAND,
# `--set model.heard_bins=96`: the lowest 96 of the 128 mel bins): the stage trained on from make model's
# first stage ($WORK/bundled/speech) with every bin heard (`--set model.heard_bins=0`, the recipe before)
# and as the recipe now has it (make model's own $WORK/bundled/speech_tuned, else trained here), both
# calibrated as the recipe does, on val:
#   - perception_shift.py (the val speakers' voices, never trained on, through changed recordings);
#   - band_limits.py: the same voices low-passed at 4, 5 and 6 kHz and through MP3 (a codec's band);
#   - real_perception.py and real_voice_emotions.py: the real recordings (never trained on: other people);
# and the 4-kHz stage trained again with seed 1 (perception_shift.py and real_perception.py): how far two
# trainings of it lie apart.
# Reports in experiments/speech_training/reports/heard_bins/ (val only). About 70 min on 2 CPU cores once make model's
# first speech stage is trained; every step resumes.
# Usage: experiments/speech_training/heard_bins.sh
set -euo pipefail
cd "$(dirname "$0")/../.."
source experiments/common.sh
source experiments/recipe.sh
BUNDLED=$WORK/bundled
RUN=$WORK/heard_bins
REPORT=experiments/speech_training/reports/heard_bins
mkdir -p "$RUN" "$REPORT"
grep -qs '"step": 1300' "$BUNDLED/speech/model.json" || { echo "train make model's first speech stage first" >&2; exit 1; }
speech_second_stage "$RUN/full_band" "$BUNDLED/speech" "$CACHE" "$RUN/times.txt" --set model.heard_bins=0
HEARD=$BUNDLED/speech_tuned
grep -qs '"step": 700' "$HEARD/model.json" || { HEARD=$RUN/heard96
    speech_second_stage "$HEARD" "$BUNDLED/speech" "$CACHE" "$RUN/times.txt"; }
speech_calibrated full_band_calibrated "$RUN/full_band" --real-voices "$REAL_VOICES"
speech_calibrated heard96_calibrated "$HEARD" --real-voices "$REAL_VOICES"
perception_val full_band_calibrated heard96_calibrated
[ -f "$REPORT/band_limits_val.md" ] || .venv/bin/python experiments/speech_training/band_limits.py "$CACHE" "$REPORT" \
    full_band="$RUN/full_band_calibrated" heard96="$RUN/heard96_calibrated"
[ -f "$REPORT/real/real_perception.md" ] || \
    real_reports full_band="$RUN/full_band_calibrated" heard96="$RUN/heard96_calibrated"
speech_second_stage "$RUN/heard96_seed1" "$BUNDLED/speech" "$CACHE" "$RUN/times.txt" --seed 1
speech_calibrated heard96_seed1_calibrated "$RUN/heard96_seed1" --real-voices "$REAL_VOICES"
perception_val heard96_seed1_calibrated
[ -f "$REPORT/real_seed1/real_perception.md" ] || .venv/bin/python experiments/real_perception.py "$REPORT/real_seed1" \
    heard96="$RUN/heard96_calibrated" heard96_seed1="$RUN/heard96_seed1_calibrated"
